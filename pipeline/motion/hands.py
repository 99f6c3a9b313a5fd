"""Hands in 3D: the hand model's metric hand, hung on the lifted wrist, in the world.

The hand landmark model gives each hand's 21 points in metres about the hand, turned to the
image's orientation (x right, y down, z away from the camera: the camera frame's axes, as the
lifted joints are), so a hand's shape needs no lifting of its own. Here it becomes wrist-relative
(``hand_shapes``), rides through the motion files beside the joints (HP-filtered, resampled to
24 fps), and the ground stage turns it into the world with the clip's camera rotation, fits one
hand skeleton per dancer (each finger bone at its median length over the frames the model is sure
of either hand: ``bone_lengths``, ``fit_hand_skeleton``) and hangs it on each world wrist
(``world_hands``). The model guesses each hand's metric size on its own; a dancer's two hands are
one size.

A frame where the model is unsure of a hand (presence under ``MIN_PRESENCE``) takes the hand's
shape drawn between the nearest sure frames (held before the first and after the last), so the
filter never sees a hand that was not there; the presence itself is carried as the hand's
confidence. A hand the model is never sure of in a clip has no shape (NaN in the world).
"""

from __future__ import annotations

import numpy as np

from pipeline.pose.pose2dfile import HAND_PARENTS, MIN_PRESENCE

H36M_WRISTS = (13, 16)  # left, right wrist of the H36M-17 joints


def hand_shapes(hands_world: np.ndarray, presence: np.ndarray,
                min_presence: float = MIN_PRESENCE) -> tuple[np.ndarray, np.ndarray]:
    """(T x 2 x 21 x 3 wrist-relative hands, camera axes, metres; T x 2 presence) from pose2d's
    ``hands_world`` and the hands' presence (T x 2): unsure frames take the shape drawn between the
    nearest sure ones; a hand never sure is all zeros (its presence says so)."""
    shapes = np.asarray(hands_world, np.float64) - np.asarray(hands_world, np.float64)[:, :, :1]
    presence = np.asarray(presence, np.float32)
    frames = np.arange(len(shapes))
    for side in range(2):
        sure = presence[:, side] >= min_presence
        if not sure.any():
            shapes[:, side] = 0.0
            continue
        flat = shapes[sure, side].reshape(int(sure.sum()), -1)
        filled = np.column_stack([np.interp(frames, frames[sure], flat[:, c]) for c in range(flat.shape[1])])
        shapes[:, side] = filled.reshape(len(frames), 21, 3)
    return shapes.astype(np.float32), presence


def bone_lengths(shapes: np.ndarray, presence: np.ndarray, min_presence: float = MIN_PRESENCE) -> np.ndarray | None:
    """Each hand bone's median length (20) over the frames and hands (``shapes`` T x H x 21 x 3,
    ``presence`` T x H) where a hand is sure; None where none is."""
    shapes = np.asarray(shapes, np.float64)
    sure = np.asarray(presence) >= min_presence
    if not sure.any():
        return None
    lengths = np.linalg.norm(shapes[:, :, 1:] - shapes[:, :, list(HAND_PARENTS[1:])], axis=-1)
    return np.median(lengths[sure], axis=0)


def fit_hand_skeleton(shapes: np.ndarray, presence: np.ndarray, min_presence: float = MIN_PRESENCE,
                      lengths: np.ndarray | None = None) -> np.ndarray:
    """One hand's wrist-relative points (T x 21 x 3) with every bone at ``lengths`` (default: its
    median length over the frames where the hand is sure, ``presence`` T), each bone keeping its direction."""
    shapes = np.asarray(shapes, np.float64)
    if lengths is None:
        lengths = bone_lengths(shapes[:, None], np.asarray(presence)[:, None], min_presence)
    if lengths is None:
        return shapes.copy()
    bones = shapes[:, 1:] - shapes[:, list(HAND_PARENTS[1:])]
    directions = bones / np.maximum(np.linalg.norm(bones, axis=-1), 1e-9)[..., None]
    out = np.zeros_like(shapes)
    for child, parent in enumerate(HAND_PARENTS[1:], start=1):  # parents come before their children
        out[:, child] = out[:, parent] + directions[:, child - 1] * lengths[child - 1]
    return out


def world_hands(shapes: np.ndarray, presence: np.ndarray, rotation: np.ndarray, wrists: np.ndarray,
                min_presence: float = MIN_PRESENCE) -> np.ndarray:
    """World hands (T x 2 x 21 x 3): wrist-relative camera-frame ``shapes`` (T x 2 x 21 x 3) with one
    skeleton for both hands (``bone_lengths`` of the sure frames of either), turned by the camera's
    ``rotation`` (camera -> world, 3 x 3) and hung on the world ``wrists`` (T x 2 x 3, left then
    right); NaN for a hand never sure in the clip."""
    out = np.full(np.shape(shapes), np.nan)
    lengths = bone_lengths(shapes, presence, min_presence)
    for side in range(2):
        if (np.asarray(presence)[:, side] >= min_presence).any():
            fitted = fit_hand_skeleton(shapes[:, side], presence[:, side], min_presence, lengths)
            out[:, side] = np.asarray(wrists, np.float64)[:, side, None] + fitted @ np.asarray(rotation).T
    return out.astype(np.float32)
