"""A clip grounded in the world, as the corpus stores it: gravity and floor, its root path,
one skeleton, foot contact with pinned feet, and joint rotations (6D) on that skeleton."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.motion.world.bones import apply_skeleton, bone_length_cv, fit_skeleton
from pipeline.motion.world.contact import carry_feet, foot_contact, pin_feet, skating
from pipeline.motion.world.gravity import to_world
from pipeline.motion.world.rotations import BVH_JOINTS, solve_rotations

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
    feet: np.ndarray | None = None  # T x 4 x 3 world heels and toe tips riding on the ankles (None: no feet)


def ground_clip(joints_cam: np.ndarray, root: np.ndarray | None, fps: float,
                feet_cam: np.ndarray | None = None) -> GroundedClip:
    """Camera-frame root-relative joints (T x 17 x 3), the root path (T x 3 or None) and the
    heels and toe tips (T x 4 x 3, like the joints, or None)."""
    joints_cam = joints_cam.astype(np.float64)
    if feet_cam is not None:
        joints_cam = np.concatenate([joints_cam, feet_cam.astype(np.float64)], 1)
    everything, camera = to_world(joints_cam, root=None if root is None else root.astype(np.float64))
    world = everything[:, :17]
    fitted = apply_skeleton(world, fit_skeleton(world))
    feet = None if feet_cam is None else carry_feet(everything[:, 17:], world, fitted)
    # Contact stays judged at the ankles: on lifted motion the heels and toes did no better
    # (benchmarks/world.py, README "Root path, world frame").
    contact = foot_contact(fitted, fps)
    motion = solve_rotations(pin_feet(fitted, contact))  # pinning bends legs: rotations of the final pose
    six = motion.local[..., :, :2].transpose(0, 1, 3, 2).reshape(len(world), len(BVH_JOINTS), 6)
    return GroundedClip(motion.joints, contact, fit_skeleton(motion.joints), six, camera.pitch_deg,
                        camera.roll_deg, bone_length_cv(world), skating(fitted, contact, fps),
                        skating(motion.joints, contact, fps),
                        None if feet is None else carry_feet(feet, fitted, motion.joints))
