"""pose2d stage: data/segments -> data/pose2d/<segment_id>.parquet (top-k largest people per frame)."""

from __future__ import annotations

import logging
import sys
from dataclasses import replace
from pathlib import Path

from pipeline.core.deferred import Deferred, make_payload
from pipeline.core.itemstage import WorkItem, is_up_to_date, run_item_stage
from pipeline.core.params import load_params, stage_params
from pipeline.core.paths import POSE2D, RAW, SEGMENTS
from pipeline.core.stage import run_stage, setup_logging
from pipeline.core.storage import code_fingerprint, fingerprint
from pipeline.ingest.catalog import read_index
from pipeline.ingest.segmentvideo import SegmentVideo
from pipeline.pose.models.loading import model_hashes, worker_files
from pipeline.pose.models.session import describe
from pipeline.pose.pose2dfile import SCHEMA_VERSION, SegmentInfo

log = logging.getLogger("dance3d.pose2d")
CODE = code_fingerprint("pipeline.pose.pose2d", "pipeline.pose.pose2dfile", "pipeline.pose.hands",
                        "pipeline.pose.models.detector", "pipeline.pose.boxes",
                        "pipeline.pose.models.pose", "pipeline.pose.models.normalize", "pipeline.pose.keyframes",
                        "pipeline.pose.parts", "pipeline.ingest.media", "pipeline.ingest.segmentvideo")


def run(root: Path) -> None:
    params = stage_params(load_params(root / "params.yaml"), "pose2d")
    opts = Deferred("pipeline.pose.pose2d:Pose2dOptions.from_params", (params,))
    # Where the models run is not what they compute: a segment done on a GPU is not redone on a CPU.
    # The runtime and precision chosen are (model_hashes: an input where not ONNX Runtime's f32).
    computed = {k: v for k, v in params.items() if k not in ("device", "runtime", "precision")}
    hashes = model_hashes(root, params)
    # With several workers a long segment is posed in parts (pipeline/pose/parts.py), joined below.
    part_seconds = float(params.get("part_seconds", 0.0)) if int(params.get("workers", 1)) > 1 else 0.0
    wholes = []
    for seg in read_index(root / SEGMENTS).values():
        inputs = {"segment": seg["fingerprint"], **hashes}
        fp = fingerprint(SCHEMA_VERSION, inputs, computed, CODE)
        out = root / POSE2D / f"{seg['segment_id']}.parquet"
        segment = SegmentInfo(seg["segment_id"], seg["fps"], int(seg["frames"]), seg["width"], seg["height"])
        job = Deferred("pipeline.pose.pose2d:Pose2dJob",
                       (SegmentVideo.from_index(root / RAW, seg), out, segment, opts, params, inputs, fp))
        wholes.append(WorkItem(seg["segment_id"], fp, (out,), job, size=float(seg["end"] - seg["start"])))
    done = [is_up_to_date(whole) for whole in wholes]
    items, split, files = [whole for whole, ok in zip(wholes, done) if ok], [], None
    if not all(done) or any((root / POSE2D).glob(".part-*")):  # work, or parts an interrupted run left
        from pipeline.pose.keyframes import keyframe_step  # the work's modules and models: only for work
        from pipeline.pose.parts import join_segment, part_files, part_items, plan_parts

        for whole in (replace(w, payload=make_payload(w.payload)) for w, ok in zip(wholes, done) if not ok):
            seg = whole.payload.segment
            spans = plan_parts(seg.frames, seg.fps, keyframe_step(seg.fps, whole.payload.opts.fps), part_seconds)
            if len(spans) == 1:
                items.append(whole)
            else:
                split.append((whole, part_items(whole, spans)))
                items += split[-1][1]
        planned = {p.outputs[0] for _, parts in split for p in parts}
        for stale in set(part_files(root / POSE2D)) - planned:
            stale.unlink()
        files = worker_files(root, params)
        log.info("models run on %s (pose2d.device: %s)", describe(files.device, files.threads), files.device)
        for path, runtime, precision in files.runtimes:
            log.info("%s runs in %s (%s)", Path(path).name, runtime, precision)
    report = run_item_stage("pose2d", items, "pipeline.pose.pose2d:pose_segment", out_dirs=[root / POSE2D],
                            params=params, setup="pipeline.pose.models.loading:load_pose_models",
                            setup_args=(files,), gpu=bool(files) and files.device != "cpu")
    for whole, parts in split:
        joined = join_segment(whole, parts)
        if joined is not None:
            report.done[whole.item_id] = joined
    for seg_id, r in sorted(report.done.items()):
        if "~" not in seg_id and r["frames_with_people"] == 0:
            log.warning("%s: no people found in any of its %d frames", seg_id, r["frames"])


def main() -> int:
    setup_logging()
    return run_stage("pose2d", run)


if __name__ == "__main__":
    sys.exit(main())
