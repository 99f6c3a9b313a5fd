"""Apply a manifest to a segment's tracks: every kept span becomes clips of one dancer.

Inside a span, gaps of up to ``max_gap`` missing frames are filled by linear
interpolation of the box and keypoints (and marked ``interpolated``); a longer gap
splits the span into separate clips. Clips shorter than ``min_clip_seconds`` are dropped
and counted. Clip ids are ``<segment_id>_<track_id>_<k>``, k counting a track's clips
from 0 in time order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyarrow as pa

from pipeline.annotate.manifests import Span
from pipeline.pose.trackfile import SegmentTracks

SCHEMA_VERSION = 1
CLEAN_SCHEMA = pa.schema(
    [
        ("clip_id", pa.string()),
        ("track_id", pa.int32()),
        ("frame", pa.int32()),
        ("time", pa.float64()),
        ("box", pa.list_(pa.float32(), 4)),
        ("keypoints", pa.list_(pa.float32(), 51)),
        ("interpolated", pa.bool_()),
    ]
)


@dataclass(frozen=True)
class CleanOptions:
    max_gap: int = 12              # missing frames filled by interpolation inside a span
    min_clip_seconds: float = 2.0  # shorter clips are dropped


@dataclass
class Clip:
    clip_id: str
    track_id: int
    frame: np.ndarray         # contiguous frame numbers
    box: np.ndarray           # n x 4
    keypoints: np.ndarray     # n x 17 x 3
    interpolated: np.ndarray  # n bool


@dataclass
class CleanResult:
    clips: list[Clip]
    dropped_short: int
    interpolated_frames: int


def _fill(frames: np.ndarray, values: np.ndarray, full: np.ndarray) -> np.ndarray:
    flat = values.reshape(len(values), -1)
    out = np.column_stack([np.interp(full, frames, flat[:, c]) for c in range(flat.shape[1])])
    return out.reshape((len(full),) + values.shape[1:]).astype(np.float32)


def apply_manifest(tracks: SegmentTracks, spans: list[Span], opts: CleanOptions) -> CleanResult:
    tolerance = 0.5 / tracks.fps
    clips: list[Clip] = []
    dropped = 0
    interpolated = 0
    counters: dict[int, int] = {}
    for span in sorted((s for s in spans if s.keep), key=lambda s: (s.track_id, s.start)):
        rows = tracks.of(span.track_id)
        rows = rows[(tracks.time[rows] >= span.start - tolerance) & (tracks.time[rows] <= span.end + tolerance)]
        if not len(rows):
            continue
        frames = tracks.frame[rows]
        breaks = np.flatnonzero(np.diff(frames) - 1 > opts.max_gap) + 1
        for piece in np.split(np.arange(len(rows)), breaks):
            f = frames[piece]
            full = np.arange(f[0], f[-1] + 1)
            if len(full) / tracks.fps < opts.min_clip_seconds:
                dropped += 1
                continue
            k = counters.get(span.track_id, 0)
            counters[span.track_id] = k + 1
            mask = ~np.isin(full, f)
            interpolated += int(mask.sum())
            clips.append(Clip(f"{tracks.segment_id}_{span.track_id}_{k}", span.track_id, full,
                              _fill(f, tracks.box[rows[piece]], full), _fill(f, tracks.keypoints[rows[piece]], full),
                              mask))
    return CleanResult(clips, dropped, interpolated)


def clips_table(clips: list[Clip], fps: float) -> pa.Table:
    n = sum(len(c.frame) for c in clips)
    if not n:
        return CLEAN_SCHEMA.empty_table()
    frame = np.concatenate([c.frame for c in clips]).astype(np.int32)
    return pa.Table.from_arrays([
        pa.array(np.concatenate([[c.clip_id] * len(c.frame) for c in clips]), pa.string()),
        pa.array(np.concatenate([np.full(len(c.frame), c.track_id) for c in clips]), pa.int32()),
        pa.array(frame, pa.int32()),
        pa.array(frame / fps, pa.float64()),
        pa.FixedSizeListArray.from_arrays(pa.array(np.concatenate([c.box for c in clips]).ravel(), pa.float32()), 4),
        pa.FixedSizeListArray.from_arrays(
            pa.array(np.concatenate([c.keypoints for c in clips]).ravel(), pa.float32()), 51),
        pa.array(np.concatenate([c.interpolated for c in clips]), pa.bool_()),
    ], schema=CLEAN_SCHEMA)
