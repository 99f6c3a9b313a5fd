"""Group windows: every dancer of a segment window in the segment's one scene, with its music.

A group window of ``W`` frames starts every ``H`` frames on the segment clock (frame 0, H, 2H,
...), and holds every dancer whose clip covers all of its frames; a window with fewer than
``MIN_DANCERS`` such dancers gives none. Dancers are in track-id order. World joints, feet and
root paths are in the segment's scene (``pipeline.motion.world.scene``: one gravity, one floor at
y = 0), x/z in metres about the group's centre over the window, so where the dancers stand
relative to each other, and how that changes, is kept. Each solo window links to the group
window of its segment that includes its clip and overlaps it most (``group_window_id``). Split by
video, like the solo windows, so a group window and its solo windows share a split.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyarrow as pa

from pipeline.corpus.windows import CHROMA_DIMS, MFCC_DIMS, tensor_column

GROUP_SCHEMA_VERSION = 2  # 2: world_hands
MIN_DANCERS = 2


@dataclass
class GroupWindow:
    meta: dict                # the scalar and list columns
    world: np.ndarray         # D x W x 17 x 3, the scene's frame
    feet: np.ndarray          # D x W x 4 x 3 (NaN without feet)
    contact: np.ndarray       # D x W x 2
    planted: np.ndarray       # D x W x 4
    mfcc: np.ndarray          # W x 39
    chroma: np.ndarray        # W x 12
    onset: np.ndarray         # W
    beat: np.ndarray          # W
    hands: np.ndarray | None = None  # D x W x 2 x 21 x 3 (NaN: none)


def group_starts(first: int, end: int, window: int, hop: int) -> list[int]:
    """Start frames on the segment grid (multiples of ``hop``) of windows inside [first, end)."""
    k = -(-first // hop) * hop
    return list(range(k, end - window + 1, hop))


def segment_group_windows(clips: list, feats, window: int, hop: int, meta: dict) -> list[GroupWindow]:
    """The group windows of one segment: ``clips`` its world clips (``worldfile.read_world``),
    ``feats`` its audio features, ``meta`` the columns every window of the segment shares."""
    if len(clips) < MIN_DANCERS:
        return []
    clips = sorted(clips, key=lambda c: (c.track_id, int(c.frame[0])))
    first, end = min(int(c.frame[0]) for c in clips), max(int(c.frame[-1]) + 1 for c in clips)
    out = []
    for k in group_starts(first, min(end, feats.frames), window, hop):
        inside = [c for c in clips if c.frame[0] <= k and c.frame[-1] >= k + window - 1]
        if len(inside) < MIN_DANCERS:
            continue
        rows = [slice(k - int(c.frame[0]), k - int(c.frame[0]) + window) for c in inside]
        world = np.stack([c.joints[r] for c, r in zip(inside, rows)]).astype(np.float64)
        feet = np.stack([c.feet[r] if c.feet is not None else np.full((window, 4, 3), np.nan)
                         for c, r in zip(inside, rows)]).astype(np.float64)
        centre = world[:, :, 0].reshape(-1, 3).mean(0) * [1.0, 0.0, 1.0]  # the group's centre over the window
        planted = np.stack([c.planted[r] if c.planted is not None else np.zeros((window, 4), bool)
                            for c, r in zip(inside, rows)])
        hands = np.stack([c.hands[r] if c.hands is not None else np.full((window, 2, 21, 3), np.nan)
                          for c, r in zip(inside, rows)]).astype(np.float64)
        out.append(GroupWindow(
            {**meta, "window_id": f"{meta['segment_id']}_g{k:06d}", "start_frame": k, "start_time": k / meta["fps"],
             "dancers": len(inside), "clip_ids": [c.clip_id for c in inside],
             "track_ids": [c.track_id for c in inside]},
            world - centre, feet - centre, np.stack([c.contact[r] for c, r in zip(inside, rows)]), planted,
            feats.mfcc[k: k + window], feats.chroma[k: k + window], feats.onset[k: k + window],
            feats.beat[k: k + window], hands - centre))
    return out


def link_solo_windows(solo: list, groups: list[GroupWindow], window: int) -> None:
    """Set each solo window's ``group_window_id``: the group window of its segment that includes its
    clip and overlaps it most (half a window at least), else ''."""
    by_clip: dict[str, list[GroupWindow]] = {}
    for g in groups:
        for clip_id in g.meta["clip_ids"]:
            by_clip.setdefault(clip_id, []).append(g)
    for w in solo:
        best, overlap = "", window / 2
        for g in by_clip.get(w.meta["clip_id"], []):
            shared = window - abs(g.meta["start_frame"] - w.meta["start_frame"])
            if shared >= overlap:
                best, overlap = g.meta["window_id"], shared
        w.meta["group_window_id"] = best


def group_schema(window: int) -> pa.Schema:
    def fixed(inner: pa.DataType, *shape: int) -> pa.DataType:
        for size in reversed(shape):
            inner = pa.list_(inner, size)
        return inner

    return pa.schema([
        ("window_id", pa.string()), ("split", pa.string()), ("video_id", pa.string()), ("url", pa.string()),
        ("licence", pa.string()), ("segment_id", pa.string()),
        ("start_frame", pa.int32()), ("start_time", pa.float64()), ("segment_start", pa.float64()),
        ("dancers", pa.int32()), ("clip_ids", pa.list_(pa.string())), ("track_ids", pa.list_(pa.int32())),
        ("world_joints", pa.list_(fixed(pa.float32(), window, 17, 3))),  # per dancer: y up, floor 0, about the group
        ("root", pa.list_(fixed(pa.float32(), window, 3))),             # per dancer: world_joints' pelvis
        ("world_feet", pa.list_(fixed(pa.float32(), window, 4, 3))),    # per dancer: heels, toe tips (NaN: none)
        ("world_hands", pa.list_(fixed(pa.float32(), window, 2, 21, 3))),  # per dancer: left, right hand (NaN: none)
        ("contact", pa.list_(fixed(pa.int8(), window, 2))),             # per dancer: left, right foot on the floor
        ("planted", pa.list_(fixed(pa.int8(), window, 4))),             # per dancer: each heel and toe tip planted
        ("camera_pitch", pa.float32()), ("camera_roll", pa.float32()),  # the scene's, degrees
        ("mfcc", fixed(pa.float32(), window, MFCC_DIMS)), ("chroma", fixed(pa.float32(), window, CHROMA_DIMS)),
        ("onset", fixed(pa.float32(), window)), ("beat", fixed(pa.int8(), window)), ("tempo", pa.float32()),
    ])


def _per_dancer(values: list[np.ndarray], dtype: pa.DataType, shape: tuple[int, ...], np_type) -> pa.Array:
    offsets = pa.array(np.concatenate([[0], np.cumsum([len(v) for v in values])]).astype(np.int32))
    flat = np.concatenate(values).astype(np_type) if values else np.zeros((0, *shape), np_type)
    return pa.ListArray.from_arrays(offsets, tensor_column(flat, dtype, shape))


def group_table(windows: list[GroupWindow], window: int) -> pa.Table:
    schema = group_schema(window)
    per_dancer = {
        "world_joints": _per_dancer([w.world for w in windows], pa.float32(), (window, 17, 3), np.float32),
        "root": _per_dancer([w.world[:, :, 0] for w in windows], pa.float32(), (window, 3), np.float32),
        "world_feet": _per_dancer([w.feet for w in windows], pa.float32(), (window, 4, 3), np.float32),
        "world_hands": _per_dancer([w.hands for w in windows], pa.float32(), (window, 2, 21, 3), np.float32),
        "contact": _per_dancer([w.contact for w in windows], pa.int8(), (window, 2), np.int8),
        "planted": _per_dancer([w.planted for w in windows], pa.int8(), (window, 4), np.int8),
    }

    def stack(attr: str, shape: tuple[int, ...]) -> np.ndarray:
        return np.stack([getattr(w, attr) for w in windows]) if windows else np.zeros((0, *shape))

    music = {
        "mfcc": tensor_column(stack("mfcc", (window, MFCC_DIMS)).astype(np.float32), pa.float32(), (window, MFCC_DIMS)),
        "chroma": tensor_column(stack("chroma", (window, CHROMA_DIMS)).astype(np.float32), pa.float32(),
                         (window, CHROMA_DIMS)),
        "onset": tensor_column(stack("onset", (window,)).astype(np.float32), pa.float32(), (window,)),
        "beat": tensor_column(stack("beat", (window,)).astype(np.int8), pa.int8(), (window,)),
    }
    tensors = {**per_dancer, **music}
    columns = [tensors[f.name] if f.name in tensors else pa.array([w.meta[f.name] for w in windows], f.type)
               for f in schema]
    return pa.Table.from_arrays(columns, schema=schema)
