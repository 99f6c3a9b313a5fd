"""The clean table (``data/clean/<segment_id>.parquet``): kept spans as clips of one dancer each.

One row per clip frame: clip_id (``<segment_id>_<track_id>_<k>``), track_id, frame
(contiguous within a clip), time (frame / fps, segment clock), box, keypoints (COCO-17
x, y, score), feet (as in the pose2d table), interpolated (the frame was a gap filled by
interpolation), and where pose2d found hands (``pose2d.hands``) hands_world (as in the pose2d
table) and hand_presence (each hand's presence: its 2D points are not carried, nothing after
clean reads them; schema 4). Metadata: the segment, whether spans came from a manifest or a proposal, and how
many clips were too short to keep.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pyarrow as pa

from pipeline.core.storage import column_array, fixed_list, read_file_table, read_meta, write_parquet
from pipeline.pose.pose2dfile import FEET, HAND_POINTS, HANDS_FIELDS, KEYPOINTS, SegmentInfo

HAND_FIELDS = [HANDS_FIELDS[1], pa.field("hand_presence", pa.list_(pa.float32(), 2))]

SCHEMA_VERSION = 4  # 2: feet and world, carried from pose2d; 3: no world (two thirds of the file, never read);
                    # 4: hands_world and hand_presence, where pose2d has hands
CLEAN_SCHEMA = pa.schema(
    [
        ("clip_id", pa.string()),
        ("track_id", pa.int32()),
        ("frame", pa.int32()),
        ("time", pa.float64()),
        ("box", pa.list_(pa.float32(), 4)),
        ("keypoints", pa.list_(pa.float32(), 51)),
        ("interpolated", pa.bool_()),
        ("feet", pa.list_(pa.float32(), FEET * 3)),
    ]
)


@dataclass
class Clip:
    clip_id: str
    track_id: int
    frame: np.ndarray         # contiguous frame numbers
    box: np.ndarray           # n x 4
    keypoints: np.ndarray     # n x 17 x 3
    interpolated: np.ndarray  # n bool
    feet: np.ndarray          # n x 4 x 3: heels and toes (score 0: none)
    hands_world: np.ndarray | None = None    # n x 2 x 21 x 3: left, right hand, metres about it (None: not asked for)
    hand_presence: np.ndarray | None = None  # n x 2: the hand model's presence


@dataclass(frozen=True)
class CleanFile:
    segment: SegmentInfo
    clips: list[Clip]
    spans_from: str        # "manifest" or "proposal"
    dropped_short: int
    fingerprint: str

    def time(self, clip: Clip) -> np.ndarray:
        return np.asarray(clip.frame, np.int32) / self.segment.fps


def clips_table(clips: list[Clip], fps: float) -> pa.Table:
    n = sum(len(c.frame) for c in clips)
    if not n:
        return CLEAN_SCHEMA.empty_table()
    frame = np.concatenate([c.frame for c in clips]).astype(np.int32)
    table = pa.Table.from_arrays([
        pa.array(np.concatenate([[c.clip_id] * len(c.frame) for c in clips]), pa.string()),
        pa.array(np.concatenate([np.full(len(c.frame), c.track_id) for c in clips]), pa.int32()),
        pa.array(frame, pa.int32()),
        pa.array(frame / fps, pa.float64()),
        fixed_list(np.concatenate([c.box for c in clips]).reshape(-1, 4)),
        fixed_list(np.concatenate([c.keypoints for c in clips]).reshape(-1, KEYPOINTS * 3)),
        pa.array(np.concatenate([c.interpolated for c in clips]), pa.bool_()),
        fixed_list(np.concatenate([c.feet for c in clips]).reshape(-1, FEET * 3)),
    ], schema=CLEAN_SCHEMA)
    if clips[0].hands_world is None:  # a segment's clips all have hands, or none has
        return table
    for field, width in zip(HAND_FIELDS, (2 * HAND_POINTS * 3, 2)):
        table = table.append_column(field, fixed_list(np.concatenate([getattr(c, field.name) for c in clips])
                                                      .reshape(-1, width)))
    return table


def write_clean(path: Path, clips: list[Clip], segment: SegmentInfo, *, spans_from: str, dropped_short: int,
                fingerprint: str, params: Mapping[str, Any], inputs: Mapping[str, str]) -> None:
    extra = {"fingerprint": fingerprint, **segment.as_meta(), "spans_from": spans_from,
             "dropped_short": dropped_short}
    write_parquet(clips_table(clips, segment.fps), path, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra=extra)


def read_clean(path: Path) -> CleanFile:
    table = read_file_table(path)
    meta = read_meta(path)
    ids = np.array(table.column("clip_id").to_pylist())
    frame = column_array(table, "frame").astype(np.int64)
    track = column_array(table, "track_id")
    box = column_array(table, "box", (4,))
    kps = column_array(table, "keypoints", (KEYPOINTS, 3))
    interp = column_array(table, "interpolated").astype(bool)
    feet = column_array(table, "feet", (FEET, 3))  # a schema-2 file's world column is left unread
    hands = {f.name: column_array(table, f.name, shape) for f, shape in zip(HAND_FIELDS, ((2, HAND_POINTS, 3), (2,)))
             if f.name in table.column_names}
    clips = []
    for clip_id in dict.fromkeys(ids):  # file order
        rows = np.flatnonzero(ids == clip_id)
        clips.append(Clip(str(clip_id), int(track[rows[0]]), frame[rows], box[rows], kps[rows], interp[rows],
                          feet[rows], **{name: values[rows] for name, values in hands.items()}))
    return CleanFile(SegmentInfo.from_meta(meta, path), clips, str(meta.get("spans_from", "manifest")),
                     int(meta.get("dropped_short", 0)), str(meta.get("fingerprint", "")))
