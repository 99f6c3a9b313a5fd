"""3D motion files (data/pose3d, data/smooth, data/motion24): one row per clip frame.

Columns: clip_id, track_id, frame (on the file's frame grid), time (s, segment clock),
joints (H36M-17 x (x, y, z), metres, root-relative, camera frame: x right, y down,
z away from the camera), interpolated (the 2D pose of that frame was filled in by clean),
filled_joints (how many 2D joints were filled because their confidence was low).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

MOTION_SCHEMA = pa.schema(
    [
        ("clip_id", pa.string()),
        ("track_id", pa.int32()),
        ("frame", pa.int32()),
        ("time", pa.float64()),
        ("joints", pa.list_(pa.float32(), 51)),
        ("interpolated", pa.bool_()),
        ("filled_joints", pa.int8()),
    ]
)


@dataclass
class MotionClip:
    clip_id: str
    track_id: int
    frame: np.ndarray         # n int
    time: np.ndarray          # n float
    joints: np.ndarray        # n x 17 x 3
    interpolated: np.ndarray  # n bool
    filled_joints: np.ndarray  # n int


def clips_to_table(clips: list[MotionClip]) -> pa.Table:
    if not clips:
        return MOTION_SCHEMA.empty_table()

    def cat(attr: str) -> np.ndarray:
        return np.concatenate([getattr(c, attr) for c in clips])

    return pa.Table.from_arrays([
        pa.array(np.concatenate([[c.clip_id] * len(c.frame) for c in clips]), pa.string()),
        pa.array(np.concatenate([np.full(len(c.frame), c.track_id) for c in clips]), pa.int32()),
        pa.array(cat("frame"), pa.int32()),
        pa.array(cat("time"), pa.float64()),
        pa.FixedSizeListArray.from_arrays(pa.array(cat("joints").astype(np.float32).ravel(), pa.float32()), 51),
        pa.array(cat("interpolated"), pa.bool_()),
        pa.array(cat("filled_joints"), pa.int8()),
    ], schema=MOTION_SCHEMA)


def read_clips(path) -> list[MotionClip]:
    table = pq.read_table(path)
    if not table.num_rows:
        return []
    ids = np.array(table.column("clip_id").to_pylist())
    frame = table.column("frame").to_numpy()
    time = table.column("time").to_numpy()
    joints = np.asarray(table.column("joints").combine_chunks().flatten(), np.float32).reshape(-1, 17, 3)
    track = table.column("track_id").to_numpy()
    interp = table.column("interpolated").to_numpy(zero_copy_only=False)
    filled = table.column("filled_joints").to_numpy()
    clips = []
    for clip_id in dict.fromkeys(ids):  # file order
        rows = np.flatnonzero(ids == clip_id)
        clips.append(MotionClip(clip_id, int(track[rows[0]]), frame[rows], time[rows], joints[rows],
                                interp[rows], filled[rows]))
    return clips
