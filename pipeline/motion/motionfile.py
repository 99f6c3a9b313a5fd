"""3D motion files (data/pose3d, data/smooth, data/motion24): one row per clip frame.

Columns: clip_id, track_id, frame (on the file's frame grid), time (s, segment clock),
joints (H36M-17 x (x, y, z), metres, root-relative, camera frame: x right, y down,
z away from the camera), interpolated (the 2D pose of that frame was filled in by clean),
filled_joints (how many 2D joints were filled because their confidence was low), root (the
root's position in the camera frame, metres, from the pose and its 2D keypoints with a
focal length assumed from the frame size: pipeline/motion/world/trajectory.py; schema 2), feet
(left heel, right heel, left toe tip, right toe tip x (x, y, z), root-relative like joints;
NaN when the lifter has no feet; schema 3), contact (the probability that the left heel, right
heel, left toe tip, right toe tip is planted, from the contact model: world/contact_model.py;
NaN without one; schema 4), feet_rays (the unit directions, camera frame, in which the left heel,
right heel, left toe tip and right toe tip are seen: their 2D keypoints and the assumed focal
length; where a planted one meets the floor fixes the root's depth; NaN without 2D feet; schema 5),
and where pose2d found hands, hands (left, right hand's 21 points, wrist-relative, metres, camera
axes: ``pipeline.motion.hands``) and hand_presence (the hand model's, per hand; schema 6).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.core.storage import column_array, fixed_list, read_meta, write_parquet

SCHEMA_VERSION = 6
MOTION_SCHEMA = pa.schema(
    [
        ("clip_id", pa.string()),
        ("track_id", pa.int32()),
        ("frame", pa.int32()),
        ("time", pa.float64()),
        ("joints", pa.list_(pa.float32(), 51)),
        ("interpolated", pa.bool_()),
        ("filled_joints", pa.int8()),
        ("root", pa.list_(pa.float32(), 3)),
        ("feet", pa.list_(pa.float32(), 12)),
        ("contact", pa.list_(pa.float32(), 4)),
        ("feet_rays", pa.list_(pa.float32(), 12)),
    ]
)
HANDS_FIELDS = [pa.field("hands", pa.list_(pa.float32(), 2 * 21 * 3)),
                pa.field("hand_presence", pa.list_(pa.float32(), 2))]


@dataclass
class MotionClip:
    clip_id: str
    track_id: int
    frame: np.ndarray         # n int
    time: np.ndarray          # n float
    joints: np.ndarray        # n x 17 x 3
    interpolated: np.ndarray  # n bool
    filled_joints: np.ndarray  # n int
    root: np.ndarray | None = None  # n x 3 root path, camera frame, metres (None: not known)
    feet: np.ndarray | None = None  # n x 4 x 3 heels and toe tips, like joints (None: the lifter has none)
    contact: np.ndarray | None = None  # n x 4 contact probabilities of the heels and toe tips (None: not known)
    feet_rays: np.ndarray | None = None  # n x 4 x 3 unit directions the heels and toes are seen in (None: unknown)
    hands: np.ndarray | None = None      # n x 2 x 21 x 3 wrist-relative hands, camera axes (None: not asked for)
    hand_presence: np.ndarray | None = None  # n x 2 the hand model's presence per hand


def clips_to_table(clips: list[MotionClip]) -> pa.Table:
    if not clips:
        return MOTION_SCHEMA.empty_table()

    def cat(attr: str) -> np.ndarray:
        return np.concatenate([getattr(c, attr) for c in clips])

    table = pa.Table.from_arrays([
        pa.array(np.concatenate([[c.clip_id] * len(c.frame) for c in clips]), pa.string()),
        pa.array(np.concatenate([np.full(len(c.frame), c.track_id) for c in clips]), pa.int32()),
        pa.array(cat("frame"), pa.int32()),
        pa.array(cat("time"), pa.float64()),
        fixed_list(cat("joints").reshape(-1, 51)),
        pa.array(cat("interpolated"), pa.bool_()),
        pa.array(cat("filled_joints"), pa.int8()),
        fixed_list(np.concatenate([c.root if c.root is not None else np.full((len(c.frame), 3), np.nan)
                                   for c in clips])),
        fixed_list(np.concatenate([c.feet.reshape(-1, 12) if c.feet is not None else np.full((len(c.frame), 12), np.nan)
                                   for c in clips])),
        fixed_list(np.concatenate([c.contact if c.contact is not None else np.full((len(c.frame), 4), np.nan)
                                   for c in clips])),
        fixed_list(np.concatenate([c.feet_rays.reshape(-1, 12) if c.feet_rays is not None
                                   else np.full((len(c.frame), 12), np.nan) for c in clips])),
    ], schema=MOTION_SCHEMA)
    if clips[0].hands is None:  # a segment's clips all have hands, or none has
        return table
    table = table.append_column(HANDS_FIELDS[0], fixed_list(cat("hands").reshape(-1, 2 * 21 * 3)))
    return table.append_column(HANDS_FIELDS[1], fixed_list(cat("hand_presence").reshape(-1, 2)))


@dataclass(frozen=True)
class MotionFile:
    clips: list[MotionClip]
    meta: dict  # segment_id, fps (of the frame grid), width, height, and the producing stage's provenance

    @property
    def fps(self) -> float:
        return float(self.meta["fps"])


def write_motion(path: Path, clips: list[MotionClip], segment_meta: Mapping[str, Any], *, fingerprint: str,
                 params: Mapping[str, Any], inputs: Mapping[str, str]) -> None:
    """``segment_meta``: segment_id, fps, width, height (and any extra facts about the file)."""
    write_parquet(clips_to_table(clips), path, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra={"fingerprint": fingerprint, **segment_meta})


def read_motion(path: Path) -> MotionFile:
    return MotionFile(read_clips(path), read_meta(path))


def clip_frame_counts(path: Path) -> dict[str, int]:
    """Frames per clip of a clean or motion table, read from its clip_id column alone."""
    from collections import Counter

    return dict(Counter(pq.read_table(path, columns=["clip_id"]).column("clip_id").to_pylist()))


def read_clips(path: Path) -> list[MotionClip]:
    table = pq.read_table(path)
    if not table.num_rows:
        return []
    ids = np.array(table.column("clip_id").to_pylist())
    frame = column_array(table, "frame")
    time = column_array(table, "time")
    joints = column_array(table, "joints", (17, 3))
    track = column_array(table, "track_id")
    interp = column_array(table, "interpolated")
    filled = column_array(table, "filled_joints")
    root = column_array(table, "root", (3,)) if "root" in table.column_names else None
    feet = column_array(table, "feet", (4, 3)) if "feet" in table.column_names else None
    contact = column_array(table, "contact", (4,)) if "contact" in table.column_names else None
    rays = column_array(table, "feet_rays", (4, 3)) if "feet_rays" in table.column_names else None
    hands = column_array(table, "hands", (2, 21, 3)) if "hands" in table.column_names else None
    presence = column_array(table, "hand_presence", (2,)) if "hand_presence" in table.column_names else None
    clips = []
    for clip_id in dict.fromkeys(ids):  # file order
        rows = np.flatnonzero(ids == clip_id)
        path = None if root is None or np.isnan(root[rows]).all() else root[rows]
        heels_toes = None if feet is None or np.isnan(feet[rows]).all() else feet[rows]
        planted = None if contact is None or np.isnan(contact[rows]).all() else contact[rows]
        seen = None if rays is None or np.isnan(rays[rows]).all() else rays[rows]
        clips.append(MotionClip(clip_id, int(track[rows[0]]), frame[rows], time[rows], joints[rows],
                                interp[rows], filled[rows], path, heels_toes, planted, seen,
                                None if hands is None else hands[rows], None if presence is None else presence[rows]))
    return clips
