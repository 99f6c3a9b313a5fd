"""train_contact stage: models/contact.onnx, metrics/contact.json (headline), reports/contact.json,
metrics/contact_loss.csv.

``train_contact.shipped: true`` (the default) takes the contact model that ships with dance3d
(``pipeline/motion/world/weights/``), trained by the ``full`` profile, with its held-out figures and
loss curve in its metadata. ``shipped: false`` trains the chosen ``profile`` on real motion capture
from ``train_contact.mocap`` or $DANCE3D_MOCAP.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from pipeline.core.errors import InputError
from pipeline.core.params import load_params, stage_params, with_profile
from pipeline.core.paths import CONTACT_MODEL, METRICS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.motion.shipped import (
    SHIPPED_CONTACT,
    copy_shipped,
    mocap_root,
    recorded_metrics,
    write_training_outputs,
)
from pipeline.motion.shipped import config_from_params as shipped_config

log = logging.getLogger("dance3d.train_contact")
SHIPPED = SHIPPED_CONTACT  # the model that ships in the package


def config_from_params(params: dict):
    from pipeline.motion.lifting.data import AugmentOptions
    from pipeline.motion.world.contact_train import ContactConfig

    return shipped_config(ContactConfig, params, AugmentOptions)


def _write_outputs(root: Path, metrics: dict, losses: list[float]) -> None:
    write_training_outputs(root, "contact", metrics, root / METRICS / "contact_loss.csv",
                           "train_bce", losses)


def run(root: Path) -> None:
    params = with_profile(stage_params(load_params(root / "params.yaml"), "train_contact"), "train_contact")
    if params.get("shipped", False):
        meta = copy_shipped(SHIPPED, root / CONTACT_MODEL)
        metrics = recorded_metrics(meta)
        _write_outputs(root, metrics, [float(x) for x in meta.get("loss_curve", "").split(",") if x])
        log.info("using the shipped contact model %s: held-out contact F1 %.3f (recorded at training)",
                 SHIPPED.name, metrics["contact_f1"])
        return
    from pipeline.motion.lifting.evaluate import split
    from pipeline.motion.mocap.sources import SOURCES, load_source, resample
    from pipeline.motion.world.contact_model import FPS
    from pipeline.motion.world.contact_train import export_onnx, provenance, train_contact

    cfg = config_from_params(params)
    mocap = mocap_root(root, params, "train_contact")
    sources = params.get("sources") or SOURCES
    sequences = [resample(s, FPS) for source in sources for s in load_source(mocap, source)]
    train, val = split(sequences, cfg.holdout)
    if not train or not val:
        raise InputError(mocap, f"need training and held-out sequences; found {len(train)} and {len(val)} "
                                "(check train_contact.sources and train_contact.holdout)")
    log.info("profile %s: training on %d sequences, holding out %d", params.get("profile"), len(train), len(val))
    result = train_contact(cfg, train, val)
    export_onnx(result.model, root / CONTACT_MODEL, provenance(cfg, train, val, result, mocap))
    log.info("held-out contact F1 %.3f (every frame planted: %.3f)", result.metrics["contact_f1"],
             result.metrics["heldout"]["all"]["f1_all_planted"])
    _write_outputs(root, result.metrics, result.losses)


def main() -> int:
    setup_logging()
    return run_stage("train_contact", run)


if __name__ == "__main__":
    sys.exit(main())
