"""smooth stage: data/pose3d -> data/smooth/<segment_id>.parquet (Hodrick-Prescott trend of every joint
coordinate, lambda from params), plus per-clip QC in the file metadata and reports/smooth.json."""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline.core.deferred import Deferred
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.metrics import write_metrics
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import POSE3D, SMOOTH
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files, read_meta
from pipeline.motion.motionfile import SCHEMA_VERSION

CODE = code_fingerprint("pipeline.motion.smoothing", "pipeline.motion.quality")


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "smooth")
    lamb = float(params.get("lambda", 1.0))
    items = []
    for src in item_files(root / POSE3D):
        inputs = {"pose3d": read_meta(src).get("fingerprint", "")}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out = root / SMOOTH / src.name
        job = Deferred("pipeline.motion.smoothing:SmoothJob", (src, out, lamb, params, inputs, fp))
        items.append(WorkItem(src.stem, fp, (out,), job))
    run_item_stage("smooth", items, "pipeline.motion.smoothing:smooth_segment", out_dirs=[root / SMOOTH],
                   params=params, light=True)
    write_motion_metrics(root)


def write_motion_metrics(root: Path) -> None:
    """reports/smooth.json: frame-weighted means of the per-clip QC over every smoothed segment."""
    qcs = [q for f in item_files(root / SMOOTH) for q in read_meta(f).get("clip_qc", {}).values()]
    frames = sum(q["frames"] for q in qcs)

    def mean(key: str) -> float:
        return round(sum(q[key] * q["frames"] for q in qcs) / frames, 4) if frames else 0.0

    metrics = {"clips": len(qcs), "frames": frames, "mean_acc_before": mean("mean_acc_before"),
               "mean_acc_after": mean("mean_acc_after"), "limb_cv": mean("limb_cv"),
               "interpolated_share": mean("interpolated_share")}
    write_metrics(root, "smooth", metrics)


def main() -> int:
    setup_logging()
    return run_stage("smooth", run)


if __name__ == "__main__":
    sys.exit(main())
