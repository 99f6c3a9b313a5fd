"""World motion files (data/world): the ground stage's output, one row per clip frame at the corpus rate.

Columns: clip_id, track_id, frame and time (the motion24 grid: frame k at k / fps s on the segment
clock), joints (H36M-17 x 3, metres, y up, the floor at y = 0, x/z about the centre of the
segment's scene, which all its clips share: ``scene.ground_scene``; one skeleton per clip,
planted feet pinned; schema 2, before which x/z were from the clip's first root position),
feet (left heel, right heel, left toe tip, right toe tip x 3, the same frame; NaN without feet),
contact (left, right foot on the floor), planted (each foot point planted), contact_probability
(the contact model's; NaN without one), rotations_6d (local joint rotations on the clip's
skeleton, ``rotations.BVH_JOINTS`` order), smpl_poses and smpl_trans (the same motion on the SMPL
tree, ``pipeline.motion.smpl.retarget``: 24 local rotations as axis-angle, the pelvis joint's path;
schema 3), and where pose2d found hands, hands (left, right hand's 21 points in the world, hung on
the wrists, one hand skeleton per clip: ``pipeline.motion.hands.world_hands``; NaN for a hand never
seen in the clip) and hand_presence (the hand model's, per hand and frame; schema 4), and with them
smpl_hand_poses (SMPL-H's 30 finger joints, axis-angle, relative to the clip's own rest hands:
``pipeline.motion.smpl.hands``; the seen hands' wrists in smpl_poses turn with the palms; schema 5).

Per clip, in the file's metadata (``clips``): bone_lengths, camera pitch and roll, the largest
limb-length CV before the one skeleton and how far it moved the joints, skating before and after
pinning, the contact share, whether contact was learned, the scale that put the clip on the
scene's floor (``scene_scale``) and the SMPL skeleton's (``smpl_scaling``); with hands, each rest
hand (``smpl_hands``: knuckles and bone lengths, for forward kinematics). Per segment (``scene``):
the scene's camera pitch and roll, whether its clips share a floor, how many clips.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from pipeline.core.storage import column_array, fixed_list, require_schema, write_parquet
from pipeline.motion.motionfile import HANDS_FIELDS  # the same two hand columns, here in the world frame
from pipeline.motion.world.rotations import BVH_JOINTS

SCHEMA_VERSION = 5  # 3: smpl_poses, smpl_trans and the clip's smpl_scaling; 4: hands, hand_presence;
#                    5: smpl_hand_poses, the seen hands' wrists turned with the palms
ROTATION_JOINTS = tuple(j.name for j in BVH_JOINTS)
ROTATIONS = len(ROTATION_JOINTS)
WORLD_SCHEMA = pa.schema([
    ("clip_id", pa.string()),
    ("track_id", pa.int32()),
    ("frame", pa.int32()),
    ("time", pa.float64()),
    ("joints", pa.list_(pa.float32(), 51)),
    ("feet", pa.list_(pa.float32(), 12)),
    ("contact", pa.list_(pa.int8(), 2)),
    ("planted", pa.list_(pa.int8(), 4)),
    ("contact_probability", pa.list_(pa.float32(), 4)),
    ("rotations_6d", pa.list_(pa.float32(), ROTATIONS * 6)),
    ("smpl_poses", pa.list_(pa.float32(), 72)),
    ("smpl_trans", pa.list_(pa.float32(), 3)),
])


@dataclass(frozen=True)
class WorldClip:
    clip_id: str
    track_id: int
    frame: np.ndarray                 # n int
    time: np.ndarray                  # n float
    joints: np.ndarray                # n x 17 x 3
    feet: np.ndarray | None           # n x 4 x 3 (None: no feet)
    contact: np.ndarray               # n x 2 bool
    planted: np.ndarray | None        # n x 4 bool (None: contact by the ankle rule)
    contact_probability: np.ndarray | None  # n x 4 (None: no contact model)
    rotations_6d: np.ndarray          # n x ROTATIONS x 6
    facts: dict                       # bone_lengths, pitch_deg, roll_deg, cv_before, fit_moved_mm, ...
    smpl_poses: np.ndarray | None = None   # n x 72 axis-angle on the SMPL tree (None: not retargeted)
    smpl_trans: np.ndarray | None = None   # n x 3 its pelvis joint (facts["smpl_scaling"]: its scale)
    hands: np.ndarray | None = None        # n x 2 x 21 x 3 world hands (None: not asked for; NaN: never seen)
    hand_presence: np.ndarray | None = None  # n x 2
    smpl_hand_poses: np.ndarray | None = None  # n x 90 SMPL-H's finger joints (facts["smpl_hands"]: rests)


def _table(clips: list[WorldClip]) -> pa.Table:
    if not clips:
        return WORLD_SCHEMA.empty_table()

    def cat(values: list[np.ndarray | None], shape: tuple[int, ...], fill: float = np.nan) -> np.ndarray:
        return np.concatenate([v.reshape(len(c.frame), -1) if v is not None
                               else np.full((len(c.frame), int(np.prod(shape))), fill) for c, v in zip(clips, values)])

    table = pa.Table.from_arrays([
        pa.array(np.concatenate([[c.clip_id] * len(c.frame) for c in clips]), pa.string()),
        pa.array(np.concatenate([np.full(len(c.frame), c.track_id) for c in clips]), pa.int32()),
        pa.array(np.concatenate([c.frame for c in clips]), pa.int32()),
        pa.array(np.concatenate([c.time for c in clips]), pa.float64()),
        fixed_list(cat([c.joints for c in clips], (51,))),
        fixed_list(cat([c.feet for c in clips], (12,))),
        fixed_list(cat([c.contact.astype(np.int8) for c in clips], (2,)).astype(np.int8), pa.int8()),
        fixed_list(cat([None if c.planted is None else c.planted.astype(np.int8) for c in clips], (4,), 0)
                   .astype(np.int8), pa.int8()),
        fixed_list(cat([c.contact_probability for c in clips], (4,))),
        fixed_list(cat([c.rotations_6d for c in clips], (ROTATIONS * 6,))),
        fixed_list(cat([c.smpl_poses for c in clips], (72,))),
        fixed_list(cat([c.smpl_trans for c in clips], (3,))),
    ], schema=WORLD_SCHEMA)
    if clips[0].hands is None:  # a segment's clips all have hands, or none has
        return table
    table = table.append_column(HANDS_FIELDS[0], fixed_list(cat([c.hands for c in clips], (2 * 21 * 3,))))
    table = table.append_column(HANDS_FIELDS[1], fixed_list(cat([c.hand_presence for c in clips], (2,))))
    return table.append_column("smpl_hand_poses", fixed_list(cat([c.smpl_hand_poses for c in clips], (90,))))


def write_world(path: Path, clips: list[WorldClip], segment_meta: Mapping[str, Any], *, fingerprint: str,
                params: Mapping[str, Any], inputs: Mapping[str, str]) -> None:
    write_parquet(_table(clips), path, schema_version=SCHEMA_VERSION, params=params, inputs=inputs,
                  extra={"fingerprint": fingerprint, "clips": {c.clip_id: c.facts for c in clips},
                         "rotation_joints": ",".join(ROTATION_JOINTS), **segment_meta})


def read_world(path: Path) -> list[WorldClip]:
    meta = require_schema(path, SCHEMA_VERSION, "world file", "re-run the ground stage")
    table = pq.read_table(path)
    if not table.num_rows:
        return []
    ids = np.array(table.column("clip_id").to_pylist())
    cols = {"frame": column_array(table, "frame"), "time": column_array(table, "time"),
            "track": column_array(table, "track_id"), "joints": column_array(table, "joints", (17, 3)),
            "feet": column_array(table, "feet", (4, 3)), "contact": column_array(table, "contact", (2,), np.int8),
            "planted": column_array(table, "planted", (4,), np.int8),
            "prob": column_array(table, "contact_probability", (4,)),
            "rot": column_array(table, "rotations_6d", (ROTATIONS, 6)),
            "poses": column_array(table, "smpl_poses", (72,)), "trans": column_array(table, "smpl_trans", (3,))}
    hands = {}
    if "hands" in table.column_names:
        hands = {"hands": column_array(table, "hands", (2, 21, 3)),
                 "hand_presence": column_array(table, "hand_presence", (2,)),
                 "smpl_hand_poses": column_array(table, "smpl_hand_poses", (90,))}
    clips = []
    for clip_id in dict.fromkeys(ids):
        rows = np.flatnonzero(ids == clip_id)
        facts = meta["clips"][clip_id]
        feet = None if np.isnan(cols["feet"][rows]).all() else cols["feet"][rows]
        prob = None if np.isnan(cols["prob"][rows]).all() else cols["prob"][rows]
        planted = cols["planted"][rows].astype(bool) if facts.get("contact_learned") else None
        clips.append(WorldClip(str(clip_id), int(cols["track"][rows[0]]), cols["frame"][rows], cols["time"][rows],
                               cols["joints"][rows], feet, cols["contact"][rows].astype(bool), planted, prob,
                               cols["rot"][rows], facts, cols["poses"][rows], cols["trans"][rows],
                               **{name: values[rows] for name, values in hands.items()}))
    return clips

