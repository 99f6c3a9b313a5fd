"""A long segment's 2D in parts, so every worker has work while it runs.

One worker poses one segment: a 40 s group dance among 12 s solos kept one core busy long after
the other had finished (on the mixed benchmark set pose2d used 1.48 of 2 cores). A segment longer
than ``part_seconds`` is posed in parts of about that length, each a work item of its own, and
joined when all are done.

The parts give the same poses as one pass: each part but the last ends on the keyframe the next
one starts on (the models pose every ``step``-th frame, ``keyframes.keyframe_step``), so the
frames between keyframes are drawn from the same two keyframes as in one pass, and that shared
keyframe is taken from the later part. (With ``det_every`` above 1 the detector's schedule starts
again at each part: a few frames may then be detected that one pass would have carried over.)
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from pipeline.core.itemstage import WorkItem, is_up_to_date
from pipeline.core.storage import fingerprint
from pipeline.pose.pose2d import Pose2dJob
from pipeline.pose.pose2dfile import Poses, write_pose2d


def plan_parts(frames: int, fps: float, step: int, seconds: float) -> list[tuple[int, int]]:
    """(first, end) frame ranges of about ``seconds`` each covering ``frames`` frames: consecutive
    parts share one frame, a multiple of ``step``; one part when the segment is not 1.5 parts long
    (or ``seconds`` is 0)."""
    count = int(round(frames / (fps * seconds))) if seconds > 0 and fps > 0 else 1
    if count < 2 or frames < 2 * step:
        return [(0, frames)]
    bounds = [0]
    for k in range(1, count):
        b = int(round(k * frames / count / step)) * step
        if bounds[-1] < b < frames - 1:
            bounds.append(b)
    return [(a, b + 1) for a, b in zip(bounds, bounds[1:])] + [(bounds[-1], frames)]


def part_path(out: Path, k: int) -> Path:
    """Where part ``k`` of the segment whose file is ``out`` is kept until the parts are joined (a
    dot file: no later stage reads it)."""
    return out.with_name(f".part-{out.stem}~{k}{out.suffix}")


def part_files(folder: Path) -> list[Path]:
    return sorted(folder.glob(".part-*")) if folder.exists() else []


def join_parts(paths: list[Path], spans: list[tuple[int, int]]) -> Poses:
    """One segment's poses from its parts' files, in order; each frame once (a part's rows before
    the next part's first frame, the last part's all)."""
    tables = []
    for k, path in enumerate(paths):
        table = pq.read_table(path)
        if k + 1 < len(spans):
            table = table.filter(pc.less(table["frame"], spans[k + 1][0]))
        tables.append(table)
    return Poses.from_table(pa.concat_tables(tables))


def part_items(whole: WorkItem, spans: list[tuple[int, int]]) -> list[WorkItem]:
    """The work items of a segment's parts (ids ``<segment>~<k>``), each its own fingerprint."""
    job: Pose2dJob = whole.payload
    fps = job.segment.fps
    out = []
    for k, span in enumerate(spans):
        path = part_path(job.out, k)
        fp = fingerprint(whole.fingerprint, list(span))
        out.append(WorkItem(f"{whole.item_id}~{k}", fp, (path,), dataclasses.replace(job, out=path, fingerprint=fp,
                                                                                     span=span),
                            whole.where, (span[1] - span[0]) / fps))
    return out


def join_segment(whole: WorkItem, parts: list[WorkItem]) -> dict | None:
    """The segment's file from its parts' once every part is done (then the parts go), with what
    ``pose2d.pose_segment`` reports; None while a part is missing (the done ones are kept)."""
    if not all(is_up_to_date(p) for p in parts):
        return None
    job: Pose2dJob = whole.payload
    poses = join_parts([p.outputs[0] for p in parts], [p.payload.span for p in parts])
    write_pose2d(job.out, poses, job.segment, fingerprint=whole.fingerprint, params=job.params, inputs=job.inputs)
    for p in parts:
        p.outputs[0].unlink(missing_ok=True)
    return {"frames": job.segment.frames, "detections": len(poses), "frames_with_people": len(np.unique(poses.frame))}
