"""pose2d stage: data/segments -> data/pose2d/<segment_id>.parquet (top-k largest people per frame)."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import pipeline.ingest.media
import pipeline.pose.models.detector
import pipeline.pose.models.pose
import pipeline.pose.pose2d
from pipeline.core.itemstage import WorkItem, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import POSE2D, SEGMENTS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint, sha256_file, write_parquet
from pipeline.ingest.catalog import read_index
from pipeline.pose.models.detector import RTMDetDetector
from pipeline.pose.models.pose import MoveNetPose, RTMPose
from pipeline.pose.models.registry import get_spec, resolve_model
from pipeline.pose.models.session import create_session
from pipeline.pose.pose2d import (
    SCHEMA_VERSION,
    Pose2dOptions,
    estimate_segment,
    poses_to_table,
)

log = logging.getLogger("dance3d.pose2d")

_MODELS: dict[str, object] = {}  # per worker process: sessions are built once, not per segment
CODE = code_fingerprint(pipeline.pose.pose2d, pipeline.pose.models.detector, pipeline.pose.models.pose, pipeline.ingest.media)


def load_models(det_path: str, det_input: tuple, pose_path: str, pose_kind: str, pose_input: tuple,
                threads: int, det_score: float, padding: float) -> None:
    _MODELS["detector"] = RTMDetDetector(create_session(Path(det_path), threads), det_input, det_score)
    session = create_session(Path(pose_path), threads)
    if pose_kind == "movenet":
        _MODELS["pose"] = MoveNetPose(session, pose_input, padding)
    elif pose_kind == "rtmpose":
        _MODELS["pose"] = RTMPose(session, pose_input, padding)
    else:
        raise ValueError(f"pose model kind {pose_kind!r} is not a 2D pose model")


def pose_segment(job: tuple) -> dict:
    segment, out, seg, opts, params, inputs, fp = job
    table, frames = poses_to_table(estimate_segment(segment, seg["fps"], _MODELS["detector"], _MODELS["pose"], opts))
    extra = {"fingerprint": fp, "segment_id": seg["segment_id"], "fps": seg["fps"], "frames": frames,
             "width": seg["width"], "height": seg["height"]}
    write_parquet(table, out, schema_version=SCHEMA_VERSION, params=params, inputs=inputs, extra=extra)
    with_people = len(set(table.column("frame").to_pylist()))
    return {"frames": frames, "detections": table.num_rows, "frames_with_people": with_people}


def model_args(root: Path, params: dict) -> tuple:
    """Resolve both models in the main process, so a missing one is one clear error up front."""
    det_spec, pose_spec = get_spec(params.get("detector", "rtmdet-nano-person")), get_spec(
        params.get("pose_model", "movenet-lightning"))
    det_path = resolve_model(det_spec.name, root)
    pose_path = resolve_model(pose_spec.name, root)
    args = (str(det_path), det_spec.input_size, str(pose_path), pose_spec.kind, pose_spec.input_size,
            int(params.get("threads", 1)), float(params.get("det_score", 0.5)), float(params.get("crop_padding", 1.25)))
    hashes = {det_spec.name: sha256_file(det_path), pose_spec.name: sha256_file(pose_path)}
    return args, hashes


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "pose2d")
    opts = Pose2dOptions(top_k=int(params.get("top_k", 5)), det_every=int(params.get("det_every", 1)))
    init_args, model_hashes = model_args(root, params)
    seg_dir, out_dir = root / SEGMENTS, root / POSE2D
    items = []
    for seg in read_index(seg_dir).values():
        inputs = {"segment": seg["fingerprint"], **model_hashes}
        fp = fingerprint(SCHEMA_VERSION, inputs, params, CODE)
        out = out_dir / f"{seg['segment_id']}.parquet"
        items.append(WorkItem(seg["segment_id"], fp, (out,),
                              (seg_dir / seg["path"], out, seg, opts, params, inputs, fp)))
    report = run_item_stage("pose2d", items, pose_segment, out_dirs=[out_dir], params=params,
                            initializer=load_models, initargs=init_args, gpu=True)
    for seg_id, r in sorted(report.done.items()):
        if r["frames_with_people"] == 0:
            log.warning("%s: no people found in any of its %d frames", seg_id, r["frames"])


def main() -> int:
    setup_logging()
    return run_stage("pose2d", run)


if __name__ == "__main__":
    sys.exit(main())
