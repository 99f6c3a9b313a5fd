"""A clip grounded in the world, as the corpus stores it: gravity and floor, its root path,
one skeleton, foot contact with pinned feet, and joint rotations (6D) on that skeleton.

With learned contact probabilities (``contact_model``, carried in the motion files) and the
feet, planted heels and toe tips drive the world: they anchor the root path
(``trajectory.refine_root``), set the floor (their median height is y = 0) and are pinned
where they stand, on it; where they are seen (the sight rays the lift stage records), the floor
they stand on fixes the root's depth (``root_on_floor``). Without them (motion files from
before, a lifter without feet) the older rules hold: the per-frame root, the floor at the lowest
foot point's 5th percentile and contact judged at the ankles (``contact.foot_contact``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.motion.world.bones import apply_skeleton, bone_length_cv, fit_skeleton
from pipeline.motion.world.contact import (
    HOLD_PROBABILITY,
    MIN_PLANTED_FRAMES,
    PLANTED_PROBABILITY,
    ContactRules,
    carry_feet,
    foot_contact,
    foot_planted,
    held_contacts,
    pin_feet,
    pin_planted,
    planted_points,
    skating,
)
from pipeline.motion.world.gravity import CameraEstimate, WorldFrame, to_world
from pipeline.motion.world.rotations import BVH_JOINTS, solve_rotations
from pipeline.motion.world.trajectory import floor_anchors, refine_root


@dataclass(frozen=True)
class GroundedClip:
    joints: np.ndarray        # T x 17 x 3 world (y up, floor y = 0), one skeleton, feet pinned
    contact: np.ndarray       # T x 2 bool: left, right foot on the floor
    bone_lengths: np.ndarray  # 16, metres, H36M_BONES order
    rotations_6d: np.ndarray  # T x len(BVH_JOINTS) x 6: first two columns of each local rotation
    pitch_deg: float
    roll_deg: float
    cv_before: float          # largest bone-length CV before the skeleton fit
    skate_before: float       # horizontal ankle speed in contact (m/s) before pinning (NaN: no contact)
    skate_after: float        # ... after
    feet: np.ndarray | None = None  # T x 4 x 3 world heels and toe tips riding on the ankles (None: no feet)
    planted: np.ndarray | None = None            # T x 4 bool: planted heels and toe tips (None: no learned contact)
    contact_probability: np.ndarray | None = None  # T x 4 the contact model's probabilities
    fit_moved: float = 0.0    # mean distance (m) the one-skeleton fit moved the joints
    camera: CameraEstimate | None = None       # the camera's estimated tilt (rotation to the world frame)
    root_camera: np.ndarray | None = None      # T x 3 the root path used, camera frame (refined when learned)


def floor_level(contacts: np.ndarray, up: np.ndarray) -> float:
    """Where the floor is along ``up`` (camera coordinates): the planted points' (N x 3) median height."""
    return float(np.median(contacts @ up))


def floor_of(joints_cam: np.ndarray, points: np.ndarray, root: np.ndarray,
             anchors: np.ndarray) -> tuple[np.ndarray, float]:
    """World up (camera coordinates) and the floor's level along it, from a root path and its
    planted points (``to_world``: up from the body and the planted points' plane, the floor at
    their median height). ``points``: heels and toe tips, root-relative, camera frame."""
    body = np.concatenate([joints_cam, joints_cam[:, :1] + points], 1)
    _, camera = to_world(body, root=root, planted=anchors)
    return camera.up, floor_level((root[:, None] + points)[anchors], camera.up)


def root_on_floor(joints_cam: np.ndarray, points: np.ndarray, per_frame: np.ndarray, anchors: np.ndarray,
                  rays: np.ndarray, frame: WorldFrame | None = None) -> np.ndarray:
    """The root path (``refine_root`` from the per-frame path ``per_frame``) held where the planted
    points (``anchors``, T x 4) are seen on the floor, the points' sight rays (``rays``, T x 4 x 3)
    meeting it. The floor is a scene's (``frame``), or, alone, that of the path refined without it
    (``floor_of``)."""
    if frame is None:
        up, level = floor_of(joints_cam, points, refine_root(per_frame, points, anchors), anchors)
    else:
        up, level = frame.camera.up, frame.floor
    return refine_root(per_frame, points, anchors, floor=floor_anchors(rays, points, anchors, up, level))


def ground_clip(joints_cam: np.ndarray, root: np.ndarray | None, fps: float,
                feet_cam: np.ndarray | None = None, contact_probability: np.ndarray | None = None, *,
                feet_rays: np.ndarray | None = None, frame: WorldFrame | None = None,
                threshold: float = PLANTED_PROBABILITY, min_frames: int = MIN_PLANTED_FRAMES,
                hold: float | None = HOLD_PROBABILITY) -> GroundedClip:
    """Camera-frame root-relative joints (T x 17 x 3), the root path (T x 3 or None), the heels
    and toe tips (T x 4 x 3, like the joints, or None) and their contact probabilities (T x 4 or
    None; a point is planted above ``threshold`` for ``min_frames`` frames in a row, and stays
    planted while above ``hold``), and the directions they are seen in (T x 4 x 3 or None). With a
    scene's ``frame`` (``scene.scene_frame``) the clip is put in that frame, on its floor."""
    joints_cam = joints_cam.astype(np.float64)
    learned = contact_probability is not None and feet_cam is not None and root is not None
    planted = anchors = None
    if learned:
        # The sure contacts anchor the path and the floor; the held ones are pinned too (a foot
        # that still stands must not slide), but their edges are where a foot may already move.
        anchors = planted_points(contact_probability, threshold, min_frames)
        planted = held_contacts(anchors, contact_probability, hold, threshold)
        per_frame, points = root.astype(np.float64), feet_cam.astype(np.float64) - joints_cam[:, :1]
        if feet_rays is not None and anchors.any():
            root = root_on_floor(joints_cam, points, per_frame, anchors, feet_rays.astype(np.float64), frame)
        else:
            root = refine_root(per_frame, points, anchors)
    if feet_cam is not None:
        joints_cam = np.concatenate([joints_cam, feet_cam.astype(np.float64)], 1)
    everything, camera = to_world(joints_cam, root=None if root is None else root.astype(np.float64),
                                  planted=anchors, frame=frame)
    world = everything[:, :17]
    fitted = apply_skeleton(world, fit_skeleton(world))
    feet = None if feet_cam is None else carry_feet(everything[:, 17:], world, fitted)
    if learned:
        contact = foot_planted(planted)
        pinned, feet = pin_planted(fitted, feet, planted)
    else:
        contact = foot_contact(fitted, fps)
        pinned = pin_feet(fitted, contact)
    motion = solve_rotations(pinned)  # pinning bends legs: rotations of the final pose
    six = motion.local[..., :, :2].transpose(0, 1, 3, 2).reshape(len(world), len(BVH_JOINTS), 6)
    return GroundedClip(motion.joints, contact, fit_skeleton(motion.joints), six, camera.pitch_deg,
                        camera.roll_deg, bone_length_cv(world), skating(fitted, contact, fps),
                        skating(motion.joints, contact, fps),
                        None if feet is None else carry_feet(feet, pinned, motion.joints), planted,
                        None if contact_probability is None else np.asarray(contact_probability, np.float32),
                        float(np.linalg.norm(fitted - world, axis=-1).mean()), camera, root)


def ground_motion(clip, fps: float, rules: ContactRules = ContactRules(),
                  frame: WorldFrame | None = None) -> GroundedClip:
    """``ground_clip`` on a motion file's clip (``motionfile.MotionClip``), with all it carries,
    with the contact ``rules``; in a scene's ``frame`` if given."""
    return ground_clip(clip.joints, clip.root, fps, clip.feet, clip.contact, feet_rays=clip.feet_rays, frame=frame,
                       threshold=rules.threshold, min_frames=rules.min_frames, hold=rules.hold)
