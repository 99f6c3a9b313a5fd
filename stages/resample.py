"""resample stage: data/smooth -> data/motion24/<segment_id>.parquet (cubic spline, exactly 24 fps:
frame k at k / 24 s on the segment clock)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import pipeline.motion.resample
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import MOTION24, SMOOTH
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, item_files, read_meta, write_parquet
from pipeline.motion.motionfile import MotionClip, clips_to_table, read_clips
from pipeline.motion.resample import TARGET_FPS, resample_cubic

SCHEMA_VERSION = 1
CODE = code_fingerprint(pipeline.motion.resample)


def resample_segment(job: tuple) -> dict:
    src, out, params, inputs, fp = job
    meta = read_meta(src)
    clips = []
    for clip in read_clips(src):
        frames, joints = resample_cubic(clip.time, clip.joints)
        if not len(frames):
            continue
        near = np.clip(np.searchsorted(clip.time, frames / TARGET_FPS), 0, len(clip.time) - 1)
        clips.append(MotionClip(clip.clip_id, clip.track_id, frames, frames / TARGET_FPS, joints.astype(np.float32),
                                clip.interpolated[near], clip.filled_joints[near]))
    extra = {"fingerprint": fp, "fps": TARGET_FPS, "source_fps": meta.get("fps"),
             **{k: meta.get(k) for k in ("segment_id", "width", "height")}}
    write_parquet(clips_to_table(clips), out, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra=extra)
    return {"clips": len(clips)}


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "resample")
    items = []
    for src in item_files(root / SMOOTH):
        inputs = {"smooth": read_meta(src).get("fingerprint", "")}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out = root / MOTION24 / src.name
        items.append(WorkItem(src.stem, fp, (out,), (src, out, params, inputs, fp)))
    run_item_stage("resample", items, resample_segment, out_dirs=[root / MOTION24], params=params)


def main() -> int:
    setup_logging()
    return run_stage("resample", run)


if __name__ == "__main__":
    sys.exit(main())
