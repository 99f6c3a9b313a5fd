"""Forward kinematics on the SMPL tree, and the rotation formats the field's files use
(axis-angle ``smpl_poses``, 6D: the first two columns of each rotation matrix, as EDGE's)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.motion.smpl.skeleton import PARENTS, REST_OFFSETS


def global_rotations(local: np.ndarray, parents: tuple[int, ...] = PARENTS) -> np.ndarray:
    """T x J x 3 x 3 world rotations of each joint from its local ones (SMPL's tree, or ``parents``)."""
    out = np.empty_like(local)
    for j, p in enumerate(parents):
        out[:, j] = local[:, j] if p < 0 else out[:, p] @ local[:, j]
    return out


def forward(local: np.ndarray, trans: np.ndarray, scale: float = 1.0, offsets: np.ndarray = REST_OFFSETS,
            parents: tuple[int, ...] = PARENTS) -> np.ndarray:
    """T x J x 3 joint positions: local rotations (T x J x 3 x 3), the pelvis path (T x 3) and the
    skeleton's scale (``smpl_scaling``: the rest offsets times it; other ``offsets`` to measure, or
    with ``parents``, SMPL-H's)."""
    glob = global_rotations(local, parents)
    out = np.empty(local.shape[:2] + (3,))
    for j, p in enumerate(parents):
        out[:, j] = trans if p < 0 else out[:, p] + glob[:, p] @ (scale * offsets[j])
    return out


def to_axis_angle(local: np.ndarray) -> np.ndarray:
    """T x 72: AIST++'s ``smpl_poses`` (axis-angle, radians, joint-major) from T x 24 x 3 x 3."""
    frames = len(local)
    return Rotation.from_matrix(local.reshape(-1, 3, 3)).as_rotvec().reshape(frames, -1)


def from_axis_angle(poses: np.ndarray) -> np.ndarray:
    """T x 24 x 3 x 3 from ``smpl_poses`` (T x 72)."""
    frames = len(poses)
    return Rotation.from_rotvec(np.asarray(poses, np.float64).reshape(-1, 3)).as_matrix().reshape(frames, -1, 3, 3)


def to_6d_rows(local: np.ndarray) -> np.ndarray:
    """T x J x 6: the first two rows of each rotation matrix, EDGE's 6D (``ax_to_6v``: PyTorch3D's
    ``matrix_to_rotation_6d``, which keeps rows of the matrices that act on column vectors)."""
    return local[..., :2, :].reshape(local.shape[:-2] + (6,))
