"""track stage: data/pose2d -> data/tracks/<segment_id>.parquet (+ track_id), data/qc/<segment_id>.mp4."""

from __future__ import annotations

import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

import pipeline.pose.qc
import pipeline.pose.tracking
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import POSE2D, QC, SEGMENTS, TRACKS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, read_meta, write_parquet
from pipeline.ingest.catalog import read_index
from pipeline.pose.qc import render_qc
from pipeline.pose.tracking import TrackerOptions, assign_tracks

SCHEMA_VERSION = 1
CODE = code_fingerprint(pipeline.pose.tracking, pipeline.pose.qc)


def track_segment(job: tuple) -> dict:
    pose_file, out, qc_out, segment, seg, opts, params, fp = job
    table = pq.read_table(pose_file)
    meta = read_meta(pose_file)
    frames = table.column("frame").to_numpy()
    boxes = np.asarray(table.column("box").combine_chunks().flatten(), np.float32).reshape(-1, 4)
    kps = np.asarray(table.column("keypoints").combine_chunks().flatten(), np.float32).reshape(-1, 17, 3)
    ids = assign_tracks(frames, boxes, kps, opts)
    tracked = table.append_column(pa.field("track_id", pa.int32()), pa.array(ids, pa.int32()))
    extra = {k: meta.get(k) for k in ("segment_id", "fps", "frames", "width", "height")}
    write_parquet(tracked, out, schema_version=SCHEMA_VERSION, params=params,
                  inputs={"pose2d": meta.get("fingerprint", "")}, extra={**extra, "fingerprint": fp})
    if qc_out is not None:
        render_qc(segment, seg["fps"], frames, ids, boxes, kps, qc_out, has_audio=seg["has_audio"],
                  kp_min_score=opts.kp_min_score)
    real = ids[ids >= 0]
    return {"tracks": int(len(np.unique(real))), "untracked": int((ids < 0).sum())}


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "track")
    opts = TrackerOptions(**{k: params[k] for k in asdict(TrackerOptions()) if k in params})
    qc_enabled = bool(params.get("qc_videos", True))
    index = read_index(root / SEGMENTS)
    items = []
    for seg_id, seg in index.items():
        pose_file = root / POSE2D / f"{seg_id}.parquet"
        if not pose_file.exists():
            continue  # pose2d failed for it: already in pose2d's failures
        fp = fingerprint(SCHEMA_VERSION, read_meta(pose_file).get("fingerprint"), params, CODE)
        out = root / TRACKS / f"{seg_id}.parquet"
        qc_out = root / QC / f"{seg_id}.mp4" if qc_enabled else None
        outputs = (out, qc_out) if qc_out else (out,)
        items.append(WorkItem(seg_id, fp, outputs,
                              (pose_file, out, qc_out, root / SEGMENTS / seg["path"], seg, opts, params, fp)))
    run_item_stage("track", items, track_segment, out_dirs=[root / TRACKS, root / QC], params=params)


def main() -> int:
    setup_logging()
    return run_stage("track", run)


if __name__ == "__main__":
    sys.exit(main())
