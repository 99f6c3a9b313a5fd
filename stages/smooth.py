"""smooth stage: data/pose3d -> data/smooth/<segment_id>.parquet (Hodrick-Prescott trend of every joint
coordinate, lambda from params), plus per-clip QC in the file metadata and metrics/smooth.json."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

import pipeline.motion.quality
import pipeline.motion.smoothing
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import METRICS, POSE3D, SMOOTH
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files, read_meta, write_json, write_parquet
from pipeline.motion.motionfile import clips_to_table, read_clips
from pipeline.motion.quality import limb_length_cv, mean_acceleration
from pipeline.motion.smoothing import hp_trend

SCHEMA_VERSION = 1
CODE = code_fingerprint(pipeline.motion.smoothing, pipeline.motion.quality)


def smooth_segment(job: tuple) -> dict:
    src, out, lamb, params, inputs, fp = job
    meta = read_meta(src)
    fps = float(meta["fps"])
    clips, qc = [], {}
    for clip in read_clips(src):
        trend = hp_trend(clip.joints.reshape(len(clip.joints), -1), lamb).reshape(clip.joints.shape)
        clips.append(replace(clip, joints=trend.astype(np.float32)))
        qc[clip.clip_id] = {
            "frames": int(len(clip.frame)),
            "mean_acc_before": round(mean_acceleration(clip.joints, fps), 3),
            "mean_acc_after": round(mean_acceleration(trend, fps), 3),
            "limb_cv": round(limb_length_cv(trend), 4),
            "interpolated_share": round(float(clip.interpolated.mean()), 4),
        }
    extra = {"fingerprint": fp, "clip_qc": qc, **{k: meta.get(k) for k in ("segment_id", "fps", "width", "height")}}
    write_parquet(clips_to_table(clips), out, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra=extra)
    return qc


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "smooth")
    lamb = float(params.get("lambda", 1.0))
    items = []
    for src in item_files(root / POSE3D):
        inputs = {"pose3d": read_meta(src).get("fingerprint", "")}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out = root / SMOOTH / src.name
        items.append(WorkItem(src.stem, fp, (out,), (src, out, lamb, params, inputs, fp)))
    run_item_stage("smooth", items, smooth_segment, out_dirs=[root / SMOOTH], params=params)
    write_motion_metrics(root)


def write_motion_metrics(root: Path) -> None:
    """metrics/smooth.json: frame-weighted means of the per-clip QC over every smoothed segment."""
    qcs = [q for f in item_files(root / SMOOTH) for q in read_meta(f).get("clip_qc", {}).values()]
    frames = sum(q["frames"] for q in qcs)

    def mean(key: str) -> float:
        return round(sum(q[key] * q["frames"] for q in qcs) / frames, 4) if frames else 0.0

    metrics = {"clips": len(qcs), "frames": frames, "mean_acc_before": mean("mean_acc_before"),
               "mean_acc_after": mean("mean_acc_after"), "limb_cv": mean("limb_cv"),
               "interpolated_share": mean("interpolated_share")}
    write_json(root / METRICS / "smooth.json", metrics)


def main() -> int:
    setup_logging()
    return run_stage("smooth", run)


if __name__ == "__main__":
    sys.exit(main())
