"""The SMPL-skeleton motion as a BVH file (``bvh_export.write_bvh``): SMPL's 24 joints by their
names, the rest offsets times the clip's ``smpl_scaling``, the pelvis path, metres, y up; the
rest pose is SMPL's T-pose facing +z."""

from __future__ import annotations

import numpy as np

from pipeline.motion.smpl.kinematics import forward, from_axis_angle
from pipeline.motion.smpl.skeleton import JOINTS, PARENTS, REST_OFFSETS
from pipeline.motion.world.rotations import BvhJointSpec, SkeletonMotion

SMPL_BVH_JOINTS = tuple(BvhJointSpec(name, parent, None, np.zeros(3)) for name, parent in zip(JOINTS, PARENTS))


def smpl_skeleton_motion(poses: np.ndarray, trans: np.ndarray, scale: float) -> SkeletonMotion:
    """A ``SkeletonMotion`` on the SMPL tree from ``smpl_poses`` (T x 72), ``smpl_trans`` (T x 3)
    and ``smpl_scaling``; its ``joints`` are the 24 SMPL joints by forward kinematics."""
    local = from_axis_angle(poses)
    trans = np.asarray(trans, np.float64)
    return SkeletonMotion(scale * REST_OFFSETS, trans, local, forward(local, trans, scale), SMPL_BVH_JOINTS)
