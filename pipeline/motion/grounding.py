"""A clip grounded in the world, as the corpus stores it: gravity and floor, its root path,
one skeleton, foot contact with pinned feet, and joint rotations (6D) on that skeleton."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.motion.bones import apply_skeleton, bone_length_cv, fit_skeleton
from pipeline.motion.bvh_export import BVH_JOINTS, solve_rotations
from pipeline.motion.contact import foot_contact, pin_feet, skating
from pipeline.motion.world import to_world

ROTATION_JOINTS = tuple(j.name for j in BVH_JOINTS)


@dataclass(frozen=True)
class GroundedClip:
    joints: np.ndarray        # T x 17 x 3 world (y up, floor y = 0), one skeleton, feet pinned
    contact: np.ndarray       # T x 2 bool: left, right foot on the floor
    bone_lengths: np.ndarray  # 16, metres, H36M_BONES order
    rotations_6d: np.ndarray  # T x len(ROTATION_JOINTS) x 6: first two columns of each local rotation
    pitch_deg: float
    roll_deg: float
    cv_before: float          # largest bone-length CV before the skeleton fit
    skate_before: float       # horizontal ankle speed in contact (m/s) before pinning (NaN: no contact)
    skate_after: float        # ... after


def ground_clip(joints_cam: np.ndarray, root: np.ndarray | None, fps: float) -> GroundedClip:
    """Camera-frame root-relative joints (T x 17 x 3) and the root path (T x 3 or None)."""
    joints_cam = joints_cam.astype(np.float64)
    world, camera = to_world(joints_cam, root=None if root is None else root.astype(np.float64))
    fitted = apply_skeleton(world, fit_skeleton(world))
    contact = foot_contact(fitted, fps)
    motion = solve_rotations(pin_feet(fitted, contact))  # pinning bends legs: rotations of the final pose
    six = motion.local[..., :, :2].transpose(0, 1, 3, 2).reshape(len(world), len(BVH_JOINTS), 6)
    return GroundedClip(motion.joints, contact, fit_skeleton(motion.joints), six, camera.pitch_deg,
                        camera.roll_deg, bone_length_cv(world), skating(fitted, contact, fps),
                        skating(motion.joints, contact, fps))
