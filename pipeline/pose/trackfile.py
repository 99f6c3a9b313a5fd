"""The tracks table (``data/tracks/<segment_id>.parquet``): a track id for each pose2d row.

The file holds only what tracking adds: ``frame``, ``person`` and ``track_id`` (-1 for detections
that never formed a real track), one row per row of the pose2d file it numbers, in that file's
order. Its metadata names that file (relative to the tracks file) and its fingerprint;
``read_tracks`` joins the two and refuses a pose2d file that has changed since. (Schema 2 copied
every pose2d column, doubling the 2D data on disk.)
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.core.storage import column_array, require_schema, write_parquet
from pipeline.pose.pose2dfile import Poses, SegmentInfo, read_pose2d

SCHEMA_VERSION = 3  # 3: the track ids alone, beside the pose2d file (2: every pose2d column repeated)
TRACKS_SCHEMA = pa.schema([("frame", pa.int32()), ("person", pa.int8()), ("track_id", pa.int32())])


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
    drawn: np.ndarray      # N bool: drawn between two keyframes, not posed (pose2d's ``interpolated``)
    hands: np.ndarray | None = None  # N x 2 x 21 x 3 (pose2d's ``hands``; None: not asked for)
    hands_world: np.ndarray | None = None  # N x 2 x 21 x 3 metres about each hand (pose2d's ``hands_world``)

    def of(self, track_id: int) -> np.ndarray:
        """Row indices of one track, in frame order."""
        return np.flatnonzero(self.track_id == track_id)

    @property
    def ids(self) -> list[int]:
        return sorted(int(t) for t in np.unique(self.track_id) if t >= 0)


def write_tracks(path: Path, pose2d: Path, poses: Poses, track_id: np.ndarray, segment: SegmentInfo, *,
                 fingerprint: str, params: Mapping[str, Any], inputs: Mapping[str, str]) -> None:
    """The track ids of ``poses``, the rows of the pose2d file ``pose2d`` in its order."""
    table = pa.table({"frame": pa.array(poses.frame, pa.int32()), "person": pa.array(poses.person, pa.int8()),
                      "track_id": pa.array(track_id, pa.int32())}, schema=TRACKS_SCHEMA)
    write_parquet(table, path, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra={"fingerprint": fingerprint, "pose2d": os.path.relpath(pose2d, Path(path).parent),
                         **segment.as_meta()})


def read_tracks(path: Path) -> SegmentTracks:
    """The tracks file joined with the pose2d file it numbers."""
    from pipeline.core.errors import InputError

    meta = require_schema(path, SCHEMA_VERSION, "a tracks file of", "run `dvc repro track` to write it again")
    source = Path(path).parent / str(meta.get("pose2d", ""))
    if not meta.get("pose2d") or not source.is_file():
        raise InputError(path, f"its pose2d file {source} is missing: run `dvc repro track`")
    pose2d = read_pose2d(source)
    made_from = (meta.get("inputs") or {}).get("pose2d")
    if made_from and made_from != pose2d.fingerprint:
        raise InputError(path, f"made from another version of {source} (fingerprint {made_from[:12]}, now "
                               f"{pose2d.fingerprint[:12]}): run `dvc repro track`")
    table = pq.read_table(path)
    poses = pose2d.poses
    frame, person = column_array(table, "frame").astype(np.int64), column_array(table, "person").astype(np.int64)
    if len(frame) != len(poses.frame) or (frame != poses.frame).any() or (person != poses.person).any():
        raise InputError(path, f"its rows do not match those of {source}: run `dvc repro track`")
    segment = pose2d.segment
    return SegmentTracks(
        segment_id=segment.segment_id, fps=segment.fps, frames_total=segment.frames, width=segment.width,
        height=segment.height, frame=poses.frame.astype(np.int64), time=np.asarray(poses.time, np.float64),
        track_id=column_array(table, "track_id").astype(np.int64), box=np.asarray(poses.box),
        keypoints=np.asarray(poses.keypoints), fingerprint=str(meta.get("fingerprint", "")),
        feet=np.asarray(poses.feet), drawn=poses.interpolated_mask(), hands=poses.hands,
        hands_world=poses.hands_world,
    )
