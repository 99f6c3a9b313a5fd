"""One skeleton per dancer: constant bone lengths for a clip, every frame made to respect them.

A lifter predicts each frame on its own, so bone lengths wander (limb-length CV of several
per cent on real video). ``fit_skeleton`` takes each bone's median length over the clip, left
and right averaged (one body), and ``apply_skeleton`` rebuilds every frame from the root
outwards keeping each bone's direction: the least change that gives exact lengths when
directions are kept (the pose's angles are untouched; only lengths move).
"""

from __future__ import annotations

import numpy as np

from pipeline.motion.mocap.skeleton import H36M_BONE_PAIRS, H36M_BONES

# Parent of each H36M-17 joint (-1: the root, the pelvis).
H36M_PARENTS = (-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15)


def fit_skeleton(joints: np.ndarray) -> np.ndarray:
    """The clip's 16 bone lengths (metres, H36M_BONES order): medians, left and right averaged."""
    parents, children = np.array(H36M_BONES).T
    lengths = np.median(np.linalg.norm(joints[:, children] - joints[:, parents], axis=-1), axis=0)
    for left, right in H36M_BONE_PAIRS:
        lengths[[left, right]] = lengths[[left, right]].mean()
    return lengths


def apply_skeleton(joints: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Every frame rebuilt from the root with the given bone lengths, bone directions kept."""
    out = joints.copy()
    bone_of = {child: k for k, (_, child) in enumerate(H36M_BONES)}
    for j in range(1, 17):  # H36M order lists every parent before its children
        p = H36M_PARENTS[j]
        direction = joints[:, j] - joints[:, p]
        norm = np.linalg.norm(direction, axis=-1, keepdims=True)
        out[:, j] = out[:, p] + lengths[bone_of[j]] * direction / np.maximum(norm, 1e-9)
    return out


def bone_length_cv(joints: np.ndarray) -> float:
    """The largest coefficient of variation of a bone's length over the clip."""
    parents, children = np.array(H36M_BONES).T
    lengths = np.linalg.norm(joints[:, children] - joints[:, parents], axis=-1)
    return float((lengths.std(0) / np.maximum(lengths.mean(0), 1e-9)).max())
