"""track stage: data/pose2d -> data/tracks/<segment_id>.parquet (+ track_id).

data/qc/<segment_id>.mp4 only with track.qc_videos: QC videos are otherwise made on request
(the review page, `dance3d qc`)."""

from __future__ import annotations

import sys
from pathlib import Path

from pipeline.core.deferred import Deferred
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import POSE2D, QC, RAW, SEGMENTS, TRACKS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, read_meta
from pipeline.ingest.catalog import read_index
from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.pose.trackfile import SCHEMA_VERSION

CODE = code_fingerprint("pipeline.pose.tracking", "pipeline.pose.qc", "pipeline.pose.trackfile",
                        "pipeline.pose.boxes", "pipeline.pose.pose2dfile")  # IoU, the OKS sigmas


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "track")
    opts = Deferred("pipeline.core.deferred:options_from_params", ("pipeline.pose.tracking:TrackerOptions", params))
    qc_enabled = bool(params.get("qc_videos", False))  # else made on request (review page, `dance3d qc`)
    items = []
    for seg_id, seg in read_index(root / SEGMENTS).items():
        pose_file = root / POSE2D / f"{seg_id}.parquet"
        if not pose_file.exists():
            continue  # pose2d failed for it: already in pose2d's failures
        fp = fingerprint(SCHEMA_VERSION, read_meta(pose_file).get("fingerprint"), params, CODE)
        out = root / TRACKS / f"{seg_id}.parquet"
        qc_out = root / QC / f"{seg_id}.mp4" if qc_enabled else None
        job = Deferred("pipeline.pose.tracking:TrackJob",
                       (pose_file, out, qc_out, SegmentVideo.from_index(root / RAW, seg), opts, params, fp))
        items.append(WorkItem(seg_id, fp, (out, qc_out) if qc_out else (out,), job))
    run_item_stage("track", items, "pipeline.pose.tracking:track_segment",
                   out_dirs=[root / TRACKS, *([root / QC] if qc_enabled else [])],
                   params=params, light=not qc_enabled)  # QC videos are the heavy part


def main() -> int:
    setup_logging()
    return run_stage("track", run)


if __name__ == "__main__":
    sys.exit(main())
