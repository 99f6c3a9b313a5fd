"""train_lifter stage: models/lifter.onnx, metrics/lifter.json (headline), reports/lifter.json, metrics/lifter_loss.csv.

``train_lifter.shipped: true`` (the default) takes the lifter that ships with dance3d
(``pipeline/motion/lifting/weights/``), trained by the ``full`` profile, with the held-out
figures and loss curve recorded in its metadata: no motion capture and no hour of training
needed. ``shipped: false`` trains with the chosen ``profile`` on real motion capture from
``train_lifter.mocap`` or $DANCE3D_MOCAP, checkpointing to $DANCE3D_CHECKPOINTS (or
~/.cache/dance3d/checkpoints): run it again after a stop and it resumes.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from pipeline.core.params import load_params, stage_params, with_profile
from pipeline.core.paths import LIFTER, METRICS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.motion.lifting.profile import train_profile
from pipeline.motion.shipped import (
    SHIPPED_LIFTER,
    copy_shipped,
    mocap_root,
    recorded_metrics,
    write_training_outputs,
)
from pipeline.motion.shipped import config_from_params as shipped_config

log = logging.getLogger("dance3d.train_lifter")
SHIPPED = SHIPPED_LIFTER  # the model that ships in the package


def config_from_params(params: dict):
    from pipeline.motion.lifting.data import AugmentOptions
    from pipeline.motion.lifting.train import LifterConfig

    return shipped_config(LifterConfig, params, AugmentOptions)


def _write_outputs(root: Path, metrics: dict, losses_mm: list[float]) -> None:
    write_training_outputs(root, "lifter", metrics, root / METRICS / "lifter_loss.csv",
                           "train_mpjpe_mm", losses_mm)


def use_shipped(root: Path, shipped: Path = SHIPPED) -> None:
    """Copy the shipped lifter to models/lifter.onnx and its recorded figures to reports/ (headline in metrics/)."""
    meta = copy_shipped(shipped, root / LIFTER)
    metrics = recorded_metrics(meta)
    _write_outputs(root, metrics, [float(x) for x in meta.get("loss_curve_mm", "").split(",") if x])
    log.info("using the shipped lifter %s: held-out MPJPE %.1f mm, P-MPJPE %.1f mm (recorded at training; "
             "re-measure with dance3d eval lifter)", shipped.name, metrics["val_mpjpe_mm"], metrics["val_p_mpjpe_mm"])


def run(root: Path) -> None:
    section = stage_params(load_params(root / "params.yaml"), "train_lifter")
    params = with_profile(section, "train_lifter")
    if params.get("shipped", False):
        use_shipped(root)
        return
    cfg = config_from_params(params)
    result = train_profile(root / LIFTER, cfg, mocap_root(root, params, "train_lifter"),
                           float(params.get("checkpoint_minutes", 5)))
    log.info("held-out MPJPE %.1f mm, P-MPJPE %.1f mm (mean pose %.1f mm); noisy 2D %.1f / %.1f mm",
             result.metrics["val_mpjpe_mm"], result.metrics["val_p_mpjpe_mm"], result.metrics["mean_pose_mpjpe_mm"],
             result.metrics["noisy_mpjpe_mm"], result.metrics["noisy_p_mpjpe_mm"])
    _write_outputs(root, result.metrics, [1000 * loss for loss in result.losses])


def main() -> int:
    setup_logging()
    return run_stage("train_lifter", run)


if __name__ == "__main__":
    sys.exit(main())
