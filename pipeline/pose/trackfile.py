"""The tracks table (``data/tracks/<segment_id>.parquet``): the pose2d rows plus ``track_id``.

``track_id`` is -1 for detections that never formed a real track. Metadata as pose2d's,
with the pose2d file's fingerprint as input.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.core.storage import column_array, read_meta, write_parquet
from pipeline.pose.pose2dfile import FEET, KEYPOINTS, POSE2D_SCHEMA, WORLD, Poses, SegmentInfo

SCHEMA_VERSION = 2  # 2: pose2d's feet and world columns
TRACKS_SCHEMA = POSE2D_SCHEMA.append(pa.field("track_id", pa.int32()))


@dataclass(frozen=True)
class SegmentTracks:
    segment_id: str
    fps: float
    frames_total: int      # frames in the segment
    width: int
    height: int
    frame: np.ndarray      # N int, sorted
    time: np.ndarray       # N float
    track_id: np.ndarray   # N int (-1: not a real track)
    box: np.ndarray        # N x 4
    keypoints: np.ndarray  # N x 17 x 3
    fingerprint: str
    feet: np.ndarray       # N x 4 x 3 (score 0: none)
    world: np.ndarray      # N x 33 x 3 (NaN: none)

    def of(self, track_id: int) -> np.ndarray:
        """Row indices of one track, in frame order."""
        return np.flatnonzero(self.track_id == track_id)

    @property
    def ids(self) -> list[int]:
        return sorted(int(t) for t in np.unique(self.track_id) if t >= 0)


def write_tracks(path: Path, poses: Poses, track_id: np.ndarray, segment: SegmentInfo, *, fingerprint: str,
                 params: Mapping[str, Any], inputs: Mapping[str, str]) -> None:
    table = poses.table().append_column(TRACKS_SCHEMA.field("track_id"), pa.array(track_id, pa.int32()))
    write_parquet(table, path, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra={"fingerprint": fingerprint, **segment.as_meta()})


def read_tracks(path: Path) -> SegmentTracks:
    table = pq.read_table(path)
    meta = read_meta(path)
    segment = SegmentInfo.from_meta(meta, path)
    return SegmentTracks(
        segment_id=segment.segment_id, fps=segment.fps, frames_total=segment.frames, width=segment.width,
        height=segment.height,
        frame=column_array(table, "frame").astype(np.int64),
        time=column_array(table, "time"),
        track_id=column_array(table, "track_id").astype(np.int64),
        box=column_array(table, "box", (4,)),
        keypoints=column_array(table, "keypoints", (KEYPOINTS, 3)),
        fingerprint=str(meta.get("fingerprint", "")),
        feet=column_array(table, "feet", (FEET, 3)),
        world=column_array(table, "world", (WORLD, 3)),
    )
