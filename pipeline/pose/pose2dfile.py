"""The pose2d table (``data/pose2d/<segment_id>.parquet``): its schema, version, reader and writer.

One row per detected person per frame (the top-k largest): frame, time (s, segment clock),
person (rank by box area, 0 = largest), box (x1, y1, x2, y2, segment pixels), box_score,
keypoints (COCO-17 x, y, score), feet (left heel, right heel, left toe, right toe as x, y,
score; score 0 where the pose model has no feet),
detected (False: the box was carried over from the previous frame's keypoints), interpolated
(True: the models did not run on this frame; it is drawn between two keyframes,
:mod:`pipeline.pose.keyframes`). The file's
metadata names the segment, its fps, frame count and frame size, the params and the models'
sha256.

Version 2 added ``feet`` and ``world``; version-1 files are redone (their fingerprint
no longer matches). Version 3 added ``interpolated`` (read as all False from version 2).
Version 4 dropped ``world`` (BlazePose's 33 metric landmarks): two thirds of every file's bytes,
and nothing after pose2d read them. Version 5 added the hands, two optional columns written only
when ``pose2d.hands`` is on: ``hands`` (left then right hand, 21 MediaPipe hand points each as x, y
and the hand's presence, 0 where the hand was not looked at: wrist unsure, hand too small or off
the picture, :func:`pipeline.pose.hands.body_hands`) and ``hands_world`` (the same points in metres
about the hand, as the hand model gives them, turned to the image's orientation).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.core.storage import column_array, fixed_list, read_meta, write_parquet

SCHEMA_VERSION = 5
# The keypoint layouts the file stores, read by every later stage and by the models that write them.
COCO17 = (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle",
)
KEYPOINTS = len(COCO17)
# COCO's per-keypoint OKS sigmas (pycocotools), for tracking's and the evaluations' similarity.
COCO_SIGMAS = np.array([0.26, 0.25, 0.25, 0.35, 0.35, 0.79, 0.79, 0.72, 0.72, 0.62, 0.62,
                        1.07, 1.07, 0.87, 0.87, 0.89, 0.89]) / 10.0
FOOT_POINTS = ("left_heel", "right_heel", "left_toe", "right_toe")
FEET = len(FOOT_POINTS)
# MediaPipe's 21 hand points (also FreiHAND's, InterHand's and COCO-WholeBody's order) and each
# point's parent: the wrist, then each finger from the palm out.
HAND_JOINTS = ("wrist", *(f"{finger}_{k}" for finger in ("thumb", "index", "middle", "ring", "pinky")
                          for k in range(1, 5)))
HAND_PARENTS = (-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19)
HAND_POINTS = len(HAND_JOINTS)
MIN_PRESENCE = 0.5  # a hand is sure from this presence on (MediaPipe's threshold); later stages trust only those
POSE2D_SCHEMA = pa.schema(
    [
        ("frame", pa.int32()),            # frame number on the segment clock (round(time * fps))
        ("time", pa.float64()),           # seconds from the segment start
        ("person", pa.int8()),            # rank by box area within the frame, 0 = largest
        ("box", pa.list_(pa.float32(), 4)),          # x1, y1, x2, y2 in segment pixels
        ("box_score", pa.float32()),
        ("keypoints", pa.list_(pa.float32(), KEYPOINTS * 3)),  # COCO-17 (x, y, score) flattened
        ("detected", pa.bool_()),         # False: box carried over from the previous keypoints
        ("feet", pa.list_(pa.float32(), FEET * 3)),        # heels and toes (x, y, score) flattened
        ("interpolated", pa.bool_()),     # True: drawn between two keyframes, not posed by the models
    ]
)
HANDS_FIELDS = [
    pa.field("hands", pa.list_(pa.float32(), 2 * HAND_POINTS * 3)),        # left, right: (x, y, presence) x 21
    pa.field("hands_world", pa.list_(pa.float32(), 2 * HAND_POINTS * 3)),  # the same in metres about the hand
]


@dataclass(frozen=True)
class SegmentInfo:
    """What every per-segment table's metadata says about its segment."""

    segment_id: str
    fps: float
    frames: int     # frames in the segment
    width: int
    height: int

    def as_meta(self) -> dict[str, Any]:
        return {"segment_id": self.segment_id, "fps": self.fps, "frames": self.frames, "width": self.width,
                "height": self.height}

    @staticmethod
    def from_meta(meta: Mapping[str, Any], path: Path) -> "SegmentInfo":
        return SegmentInfo(str(meta.get("segment_id") or Path(path).stem), float(meta["fps"]), int(meta["frames"]),
                           int(meta["width"]), int(meta["height"]))


@dataclass(frozen=True)
class Poses:
    """Per-person rows of one segment, in frame order."""

    frame: np.ndarray      # N int
    time: np.ndarray       # N float
    person: np.ndarray     # N int
    box: np.ndarray        # N x 4
    box_score: np.ndarray  # N
    keypoints: np.ndarray  # N x 17 x 3
    detected: np.ndarray   # N bool
    feet: np.ndarray       # N x 4 x 3 (score 0: no foot point)
    interpolated: np.ndarray | None = None  # N bool (None: all False, every frame posed)
    hands: np.ndarray | None = None         # N x 2 x 21 x 3 (None: hands were not asked for)
    hands_world: np.ndarray | None = None   # N x 2 x 21 x 3 metres

    def __len__(self) -> int:
        return len(self.frame)

    def table(self) -> pa.Table:
        table = pa.Table.from_arrays([
            pa.array(np.asarray(self.frame, np.int32), pa.int32()),
            pa.array(np.asarray(self.time, np.float64), pa.float64()),
            pa.array(np.asarray(self.person, np.int8), pa.int8()),
            fixed_list(np.asarray(self.box, np.float32).reshape(-1, 4)),
            pa.array(np.asarray(self.box_score, np.float32), pa.float32()),
            fixed_list(np.asarray(self.keypoints, np.float32).reshape(-1, KEYPOINTS * 3)),
            pa.array(np.asarray(self.detected, bool), pa.bool_()),
            fixed_list(np.asarray(self.feet, np.float32).reshape(-1, FEET * 3)),
            pa.array(self.interpolated_mask(), pa.bool_()),
        ], schema=POSE2D_SCHEMA)
        if self.hands is None:
            return table
        for field, values in zip(HANDS_FIELDS, (self.hands, self.hands_world)):
            flat = np.asarray(values, np.float32).reshape(-1, 2 * HAND_POINTS * 3)
            table = table.append_column(field, fixed_list(flat))
        return table

    def interpolated_mask(self) -> np.ndarray:
        """N bool: True where the row is interpolated (all False when the models posed every frame)."""
        if self.interpolated is None:
            return np.zeros(len(self.frame), bool)
        return np.asarray(self.interpolated, bool)

    @staticmethod
    def from_table(table: pa.Table) -> "Poses":
        return Poses(frame=column_array(table, "frame").astype(np.int64), time=column_array(table, "time"),
                     person=column_array(table, "person").astype(np.int64), box=column_array(table, "box", (4,)),
                     box_score=column_array(table, "box_score"),
                     keypoints=column_array(table, "keypoints", (KEYPOINTS, 3)),
                     detected=column_array(table, "detected").astype(bool),
                     feet=column_array(table, "feet", (FEET, 3)),
                     interpolated=(column_array(table, "interpolated").astype(bool)
                                   if "interpolated" in table.column_names else None),
                     hands=(column_array(table, "hands", (2, HAND_POINTS, 3))
                            if "hands" in table.column_names else None),
                     hands_world=(column_array(table, "hands_world", (2, HAND_POINTS, 3))
                                  if "hands_world" in table.column_names else None))


@dataclass(frozen=True)
class Pose2dFile:
    segment: SegmentInfo
    poses: Poses
    fingerprint: str


def write_pose2d(path: Path, poses: Poses, segment: SegmentInfo, *, fingerprint: str, params: Mapping[str, Any],
                 inputs: Mapping[str, str]) -> None:
    write_parquet(poses.table(), path, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra={"fingerprint": fingerprint, **segment.as_meta()})


def read_pose2d(path: Path) -> Pose2dFile:
    meta = read_meta(path)
    return Pose2dFile(SegmentInfo.from_meta(meta, path), Poses.from_table(pq.read_table(path)),
                      str(meta.get("fingerprint", "")))
