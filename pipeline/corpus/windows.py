"""The corpus window contract: motion clips at the corpus rate joined with their music
features, cut into overlapping windows, split by video, written as Parquet shards.

A window of ``W`` frames starting at frame k holds motion frames k .. k+W-1 of one clip
and the audio feature frames with the same numbers: both are centred at k/fps s on the
segment clock (fps = ``common.fps``, 24 by default). Beat columns give, at the dancers' beat level
(``pipeline.music.levels``), per frame a beat flag, a downbeat flag and the beat and bar phase,
and per window the beat and downbeat times and frames, the motion beats and the alignment
scores (``pipeline.music.alignment``). Windows start every ``H`` frames from the clip's first frame; a clip
shorter than one window gives none. The train/val split is by video (a hash of its id),
so the overlapping windows of one video never straddle the split.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
import pyarrow as pa

SCHEMA_VERSION = 11  # 2: beat, downbeat and motion-beat frames, alignment scores; any frame rate. 3: tags.
#                    4: world-frame joints, root path, foot contact, bone lengths, 6D rotations, camera pitch/roll
#                    5: feet, world_feet. 6: contact from the learned contact model, planted, contact_probability
#                    7: group_window_id (the group window, corpus/groups.py, that holds this one's dancer)
#                    8: smpl_poses, smpl_trans, smpl_scaling (the motion on the SMPL tree, motion/smpl)
#                    9: downbeat flags, beat and bar phase, beat and downbeat times, the dancers' beat level,
#                       the tracker, the AIST++ beat-align score beside Bailando's
#                    10: world_hands, hand_confidence (NaN where pose2d.hands is off)
#                    11: smpl_hand_poses (SMPL-H's 30 finger joints; NaN where pose2d.hands is off)
FPS = 24  # the default corpus rate
MFCC_DIMS = 39
# A window built without beat analysis (tests, benchmarks) has no beats: empty lists, NaN scores.
WORLD_DEFAULTS = {"camera_pitch": float("nan"), "camera_roll": float("nan"), "group_window_id": "",
                  "smpl_scaling": float("nan")}
BEAT_DEFAULTS = {"beat_frames": [], "downbeat_frames": [], "motion_beat_frames": [], "beat_align_score": float("nan"),
                 "beat_align_score_aistpp": float("nan"), "beat_f1": float("nan"), "beat_times": [],
                 "downbeat_times": [], "beat_level": "", "beat_level_reason": "", "beat_tracker": ""}
CHROMA_DIMS = 12
BONES = 16
ROTATION_JOINTS = 23  # pipeline.motion.world.worldfile.ROTATION_JOINTS (the BVH skeleton's joints)


def window_starts(first_frame: int, n_frames: int, window: int, hop: int) -> list[int]:
    """Start frames of the windows of a clip (every ``hop`` frames, each fully inside the clip)."""
    return [first_frame + s for s in range(0, n_frames - window + 1, hop)] if n_frames >= window else []


def split_of(video_id: str, val_fraction: float) -> str:
    """'val' or 'train', fixed by a hash of the video id (stable across runs and machines)."""
    value = int.from_bytes(hashlib.sha256(video_id.encode()).digest()[:8], "big") / 2 ** 64
    return "val" if value < val_fraction else "train"


def corpus_schema(window: int) -> pa.Schema:
    def fixed(inner: pa.DataType, size: int) -> pa.DataType:
        return pa.list_(inner, size)

    return pa.schema([
        ("window_id", pa.string()), ("split", pa.string()),
        ("video_id", pa.string()), ("url", pa.string()), ("title", pa.string()), ("channel", pa.string()),
        ("style", pa.string()), ("tags", pa.list_(pa.string())), ("licence", pa.string()),
        ("segment_id", pa.string()), ("clip_id", pa.string()), ("track_id", pa.int32()),
        ("group_window_id", pa.string()),  # the group window holding this dancer's frames ('' when none)
        ("start_frame", pa.int32()), ("start_time", pa.float64()), ("segment_start", pa.float64()),
        ("motion", fixed(fixed(fixed(pa.float32(), 3), 17), window)),
        ("world_joints", fixed(fixed(fixed(pa.float32(), 3), 17), window)),  # y up, floor 0, x/z from window start
        ("root", fixed(fixed(pa.float32(), 3), window)),                      # world_joints' pelvis: the path
        ("contact", fixed(fixed(pa.int8(), 2), window)),                      # left, right foot on the floor
        ("planted", fixed(fixed(pa.int8(), 4), window)),                      # each heel and toe tip planted
        ("contact_probability", fixed(fixed(pa.float32(), 4), window)),       # the contact model's (NaN: none)
        ("feet", fixed(fixed(fixed(pa.float32(), 3), 4), window)),            # heels, toe tips like motion (NaN: none)
        ("world_feet", fixed(fixed(fixed(pa.float32(), 3), 4), window)),      # ... like world_joints
        ("world_hands", fixed(fixed(fixed(fixed(pa.float32(), 3), 21), 2), window)),  # left, right hand, likewise
        ("hand_confidence", fixed(fixed(pa.float32(), 2), window)),          # the hand model's presence (NaN: none)
        ("rotations_6d", fixed(fixed(fixed(pa.float32(), 6), ROTATION_JOINTS), window)),
        ("bone_lengths", fixed(pa.float32(), BONES)),                         # the clip's one skeleton (m)
        ("camera_pitch", pa.float32()), ("camera_roll", pa.float32()),         # degrees, estimated per clip
        ("smpl_poses", fixed(fixed(pa.float32(), 72), window)),  # SMPL's 24 local rotations, axis-angle (AIST++)
        ("smpl_trans", fixed(fixed(pa.float32(), 3), window)),   # its pelvis joint, like world_joints
        ("smpl_scaling", pa.float32()),                           # the SMPL rest offsets' scale for this dancer
        ("smpl_hand_poses", fixed(fixed(pa.float32(), 90), window)),  # SMPL-H's finger joints (NaN: none)
        ("mfcc", fixed(fixed(pa.float32(), MFCC_DIMS), window)),
        ("chroma", fixed(fixed(pa.float32(), CHROMA_DIMS), window)),
        ("onset", fixed(pa.float32(), window)),
        ("beat", fixed(pa.int8(), window)),            # 1 on the frame nearest each beat (the beat level's)
        ("downbeat", fixed(pa.int8(), window)),        # 1 on the frame nearest each bar start
        ("beat_phase", fixed(pa.float32(), window)),   # 0 at a beat, towards 1 before the next (NaN: no beats)
        ("bar_phase", fixed(pa.float32(), window)),    # the same over bars
        ("tempo", pa.float32()),                       # BPM at the beat level
        ("beat_times", pa.list_(pa.float32())),        # music beats, seconds from the window's start
        ("downbeat_times", pa.list_(pa.float32())),    # bar starts, likewise (a subset of beat_times)
        ("beat_frames", pa.list_(pa.int32())),         # music beats: frame indices inside the window
        ("downbeat_frames", pa.list_(pa.int32())),     # bar starts (a subset of beat_frames)
        ("beat_level", pa.string()),                   # tracked, half or double: the level the dance follows
        ("beat_level_reason", pa.string()),            # why (each level's fit to the motion beats)
        ("beat_tracker", pa.string()),                 # rnn or librosa (the card says more, and the licence)
        ("motion_beat_frames", pa.list_(pa.int32())),  # kinematic beats of the window's motion
        ("beat_align_score", pa.float32()),            # beat-align score, Bailando's (NaN: no music beats)
        ("beat_align_score_aistpp", pa.float32()),     # beat-align score, AIST++'s (NaN: no motion beats)
        ("beat_f1", pa.float32()),                     # seed beat-consistency F-score, 2-frame tolerance
    ])


@dataclass
class Window:
    meta: dict            # the scalar columns
    motion: np.ndarray    # W x 17 x 3
    mfcc: np.ndarray      # W x 39
    chroma: np.ndarray    # W x 12
    onset: np.ndarray     # W
    beat: np.ndarray      # W
    world: np.ndarray | None = None      # W x 17 x 3 world joints (None: NaN columns)
    contact: np.ndarray | None = None    # W x 2
    rotations: np.ndarray | None = None  # W x ROTATION_JOINTS x 6
    feet: np.ndarray | None = None       # W x 4 x 3 heels and toe tips, camera frame like motion (None: NaN)
    world_feet: np.ndarray | None = None  # W x 4 x 3 the same in the world frame
    planted: np.ndarray | None = None     # W x 4 planted heels and toe tips (None: zeros)
    contact_probability: np.ndarray | None = None  # W x 4 (None: NaN)
    smpl_poses: np.ndarray | None = None  # W x 72 (None: NaN)
    smpl_trans: np.ndarray | None = None  # W x 3, the frame of world (None: NaN)
    downbeat: np.ndarray | None = None    # W (None: zeros)
    beat_phase: np.ndarray | None = None  # W (None: NaN)
    bar_phase: np.ndarray | None = None   # W (None: NaN)
    world_hands: np.ndarray | None = None  # W x 2 x 21 x 3 like world (None: NaN)
    hand_confidence: np.ndarray | None = None  # W x 2 (None: NaN)
    smpl_hand_poses: np.ndarray | None = None  # W x 90 (None: NaN)


def tensor_column(values: np.ndarray, dtype: pa.DataType, shape: tuple[int, ...]) -> pa.Array:
    """Rows of ``shape``-shaped tensors as nested Arrow fixed-size lists."""
    arr = pa.array(values.ravel(), dtype)
    for size in reversed(shape):
        arr = pa.FixedSizeListArray.from_arrays(arr, size)
    return arr


def windows_table(windows: list[Window], window: int) -> pa.Table:
    schema = corpus_schema(window)
    tensors = ("motion", "mfcc", "chroma", "onset", "beat", "world_joints", "root", "contact", "rotations_6d",
               "bone_lengths", "feet", "world_feet", "planted", "contact_probability", "smpl_poses", "smpl_trans",
               "downbeat", "beat_phase", "bar_phase", "world_hands", "hand_confidence", "smpl_hand_poses")
    defaults = {**BEAT_DEFAULTS, **WORLD_DEFAULTS}
    scalars = {name: [w.meta.get(name, defaults[name]) if name in defaults else w.meta[name] for w in windows]
               for name in schema.names if name not in tensors}
    n = len(windows)

    def stack(attr: str, shape: tuple) -> np.ndarray:
        return np.stack([getattr(w, attr) if getattr(w, attr) is not None else np.full(shape, np.nan)
                         for w in windows]) if n else np.zeros((0, *shape))

    world = stack("world", (window, 17, 3))
    lengths = np.stack([np.asarray(w.meta.get("bone_lengths", np.full(BONES, np.nan)), np.float32)
                        for w in windows]) if n else np.zeros((0, BONES))

    arrays = {
        "motion": tensor_column(stack("motion", (window, 17, 3)).astype(np.float32), pa.float32(), (window, 17, 3)),
        "mfcc": tensor_column(stack("mfcc", (window, MFCC_DIMS)).astype(np.float32), pa.float32(), (window, MFCC_DIMS)),
        "chroma": tensor_column(stack("chroma", (window, CHROMA_DIMS)).astype(np.float32), pa.float32(),
                          (window, CHROMA_DIMS)),
        "onset": tensor_column(stack("onset", (window,)).astype(np.float32), pa.float32(), (window,)),
        "beat": tensor_column(stack("beat", (window,)).astype(np.int8), pa.int8(), (window,)),
        "downbeat": tensor_column(np.nan_to_num(stack("downbeat", (window,))).astype(np.int8), pa.int8(), (window,)),
        "beat_phase": tensor_column(stack("beat_phase", (window,)).astype(np.float32), pa.float32(), (window,)),
        "bar_phase": tensor_column(stack("bar_phase", (window,)).astype(np.float32), pa.float32(), (window,)),
        "world_joints": tensor_column(world.astype(np.float32), pa.float32(), (window, 17, 3)),
        "root": tensor_column(world[:, :, 0].astype(np.float32), pa.float32(), (window, 3)),
        "contact": tensor_column(np.nan_to_num(stack("contact", (window, 2))).astype(np.int8), pa.int8(), (window, 2)),
        "rotations_6d": tensor_column(stack("rotations", (window, ROTATION_JOINTS, 6)).astype(np.float32), pa.float32(),
                                (window, ROTATION_JOINTS, 6)),
        "bone_lengths": tensor_column(lengths.astype(np.float32), pa.float32(), (BONES,)),
        "feet": tensor_column(stack("feet", (window, 4, 3)).astype(np.float32), pa.float32(), (window, 4, 3)),
        "world_feet": tensor_column(stack("world_feet", (window, 4, 3)).astype(np.float32), pa.float32(),
                                    (window, 4, 3)),
        "planted": tensor_column(np.nan_to_num(stack("planted", (window, 4))).astype(np.int8), pa.int8(), (window, 4)),
        "contact_probability": tensor_column(stack("contact_probability", (window, 4)).astype(np.float32), pa.float32(),
                                       (window, 4)),
        "smpl_poses": tensor_column(stack("smpl_poses", (window, 72)).astype(np.float32), pa.float32(), (window, 72)),
        "smpl_trans": tensor_column(stack("smpl_trans", (window, 3)).astype(np.float32), pa.float32(), (window, 3)),
        "world_hands": tensor_column(stack("world_hands", (window, 2, 21, 3)).astype(np.float32), pa.float32(),
                                     (window, 2, 21, 3)),
        "hand_confidence": tensor_column(stack("hand_confidence", (window, 2)).astype(np.float32), pa.float32(),
                                         (window, 2)),
        "smpl_hand_poses": tensor_column(stack("smpl_hand_poses", (window, 90)).astype(np.float32), pa.float32(),
                                         (window, 90)),
    }
    columns = [arrays[f.name] if f.name in arrays else pa.array(scalars[f.name], f.type) for f in schema]
    return pa.Table.from_arrays(columns, schema=schema)


def check_schema(path) -> None:
    """Refuse a shard written by another corpus schema, naming it and what to do."""
    from pipeline.core.storage import require_schema

    require_schema(path, SCHEMA_VERSION, "corpus", "rebuild the corpus with `dvc repro shard` (or install the "
                                                   "dance3d that wrote it)")
