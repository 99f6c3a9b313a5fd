"""train_lifter stage: real motion capture -> models/lifter.onnx, metrics/lifter.json, metrics/lifter_loss.csv.

The motion capture folder is ``train_lifter.mocap`` in params, or else $DANCE3D_MOCAP.
"""

from __future__ import annotations

import logging
import os
import sys
from dataclasses import fields
from pathlib import Path

from pipeline.core.errors import InputError
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import LIFTER, METRICS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import atomic_path, write_json

log = logging.getLogger("dance3d.train_lifter")


def config_from_params(params: dict):
    from pipeline.motion.lifting.train import LifterConfig

    known = {f.name for f in fields(LifterConfig)} - {"augment"}
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in params.items() if k in known}
    return LifterConfig(**values)


def mocap_root(root: Path, params: dict) -> Path:
    configured = params.get("mocap") or os.environ.get("DANCE3D_MOCAP", "")
    path = Path(configured) if configured else None
    if path is not None and not path.is_absolute():
        path = root / path
    if path is None or not path.is_dir():
        raise InputError(root / "params.yaml", "no motion capture folder: set train_lifter.mocap or $DANCE3D_MOCAP "
                                               "to a folder of BVH / DeepMimic / npz motion (see MOCAP.md)")
    return path


def run(root: Path) -> None:
    from pipeline.motion.lifting.train import export_onnx, load_mocap, split, train_lifter

    params = stage_params(load_params(root / "params.yaml"), "train_lifter")
    cfg = config_from_params(params)
    mocap = mocap_root(root, params)
    sequences = load_mocap(mocap, cfg)
    train, val = split(sequences, cfg.holdout)
    if not train or not val:
        raise InputError(mocap, f"need training and held-out sequences; found {len(train)} and {len(val)} "
                                "(check train_lifter.sources and train_lifter.holdout)")
    log.info("training on %d sequences, holding out %d", len(train), len(val))
    result = train_lifter(cfg, train, val)
    export_onnx(result.model, root / LIFTER, {"trained_on": ",".join(cfg.sources), "steps": len(result.losses)})
    log.info("held-out MPJPE %.1f mm, P-MPJPE %.1f mm (mean pose %.1f mm)", result.metrics["val_mpjpe_mm"],
             result.metrics["val_p_mpjpe_mm"], result.metrics["mean_pose_mpjpe_mm"])
    write_json(root / METRICS / "lifter.json", result.metrics)
    every = max(1, len(result.losses) // 200)
    with atomic_path(root / METRICS / "lifter_loss.csv") as tmp:
        tmp.write_text("step,train_mpjpe_mm\n" + "".join(
            f"{i},{1000 * loss:.2f}\n" for i, loss in enumerate(result.losses) if i % every == 0))


def main() -> int:
    setup_logging()
    return run_stage("train_lifter", run)


if __name__ == "__main__":
    sys.exit(main())
