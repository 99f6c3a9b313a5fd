"""The SMPL-skeleton motion as a BVH file (``bvh_export.write_bvh``): SMPL's 24 joints by their
names, the rest offsets times the clip's ``smpl_scaling``, the pelvis path, metres, y up; the
rest pose is SMPL's T-pose facing +z. A clip with finger rotations goes on SMPL-H's 52 joints
instead: SMPL's first 22, then 15 per hand on the clip's own rest hands (metres, unscaled: the
hand model measured them), each fingertip an End Site."""

from __future__ import annotations

import numpy as np

from pipeline.motion.smpl.hands import SMPLH_JOINTS, SMPLH_PARENTS, both_rests, rests_from_facts, smplh_offsets
from pipeline.motion.smpl.kinematics import forward, from_axis_angle
from pipeline.motion.smpl.skeleton import JOINTS, PARENTS, REST_OFFSETS
from pipeline.motion.world.rotations import BvhJointSpec, SkeletonMotion

SMPL_BVH_JOINTS = tuple(BvhJointSpec(name, parent, None, np.zeros(3)) for name, parent in zip(JOINTS, PARENTS))
SMPLH_BVH_JOINTS = tuple(BvhJointSpec(name, parent, None, np.zeros(3))
                         for name, parent in zip(SMPLH_JOINTS, SMPLH_PARENTS))


def smpl_skeleton_motion(poses: np.ndarray, trans: np.ndarray, scale: float) -> SkeletonMotion:
    """A ``SkeletonMotion`` on the SMPL tree from ``smpl_poses`` (T x 72), ``smpl_trans`` (T x 3)
    and ``smpl_scaling``; its ``joints`` are the 24 SMPL joints by forward kinematics."""
    local = from_axis_angle(poses)
    trans = np.asarray(trans, np.float64)
    return SkeletonMotion(scale * REST_OFFSETS, trans, local, forward(local, trans, scale), SMPL_BVH_JOINTS)


def smplh_skeleton_motion(poses: np.ndarray, hand_poses: np.ndarray, trans: np.ndarray, scale: float,
                          rests: tuple) -> SkeletonMotion:
    """A ``SkeletonMotion`` on SMPL-H's tree: ``smpl_poses``' first 22 joints, ``smpl_hand_poses``
    (T x 90) on the rest hands ``rests`` (an unseen hand: the other mirrored); ``joints`` are the
    52 joints by forward kinematics."""
    full = both_rests(rests)
    offsets, beyond = smplh_offsets(scale * REST_OFFSETS, full)
    local = np.concatenate([from_axis_angle(poses)[:, :22], from_axis_angle(hand_poses)], axis=1)
    trans = np.asarray(trans, np.float64)
    ends = {SMPLH_JOINTS[22 + k]: beyond[k] for k in range(2, 30, 3)}
    return SkeletonMotion(offsets, trans, local, forward(local, trans, 1.0, offsets, SMPLH_PARENTS),
                          SMPLH_BVH_JOINTS, ends)


def clip_skeleton_motion(clip) -> SkeletonMotion:
    """A world clip on SMPL-H's tree where it has finger rotations, else on SMPL's."""
    scale = float(clip.facts["smpl_scaling"])
    rests = rests_from_facts(clip.facts.get("smpl_hands") or {})
    if clip.smpl_hand_poses is None or rests == (None, None):
        return smpl_skeleton_motion(clip.smpl_poses, clip.smpl_trans, scale)
    return smplh_skeleton_motion(clip.smpl_poses, clip.smpl_hand_poses, clip.smpl_trans, scale, rests)
