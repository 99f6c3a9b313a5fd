"""train stage: data/corpus -> models/tsmt.pt, metrics/train.json (headline), reports/train.json,
metrics/train_loss.csv."""

from __future__ import annotations

import sys
from dataclasses import fields
from pathlib import Path

from pipeline.core.metrics import write_metrics
from pipeline.core.params import load_params, stage_params, with_profile
from pipeline.core.paths import CORPUS, METRICS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import atomic_path


def run(root: Path) -> None:
    from pipeline.train.loop import TrainConfig, save_model, train_tsmt
    from pipeline.train.model import TSMTConfig

    params = with_profile(stage_params(load_params(root / "params.yaml"), "train"), "train")
    model_keys = {f.name for f in fields(TSMTConfig)}
    train_keys = {f.name for f in fields(TrainConfig)} - {"model"}
    cfg = TrainConfig(**{k: v for k, v in params.items() if k in train_keys},
                      model=TSMTConfig(**(params.get("model") or {})) if set(params.get("model") or {}) <= model_keys
                      else TSMTConfig())
    model, losses = train_tsmt(root / CORPUS, cfg)
    save_model(model, root / "models/tsmt.pt")
    first, last = sum(losses[:20]) / min(20, len(losses)), sum(losses[-20:]) / min(20, len(losses))
    write_metrics(root, "train", {"steps": len(losses), "loss_first": round(first, 4), "loss_last": round(last, 4),
                                  "loss": [round(v, 4) for v in losses]})
    with atomic_path(root / METRICS / "train_loss.csv") as tmp:
        tmp.write_text("step,loss\n" + "".join(f"{i},{v:.4f}\n" for i, v in enumerate(losses)))


def main() -> int:
    setup_logging()
    return run_stage("train", run)


if __name__ == "__main__":
    sys.exit(main())
