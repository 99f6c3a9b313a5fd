"""What retargeting onto SMPL kept and what it changed: per-joint error of forward kinematics
against the world joints, foot sliding before and after, and joint angles against human ranges."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.motion.smpl.retarget import SmplMotion
from pipeline.motion.smpl.skeleton import BALL_SHARE, JOINTS, MAPPED, PARENTS, REST_OFFSETS, J

# Largest angles (degrees) a joint's local rotation may take, as a swing of its bone and a twist
# about it; hinges (knees, elbows) as a bend about their hinge axis (min, max) and what they may
# turn off it. Wide: they catch a twist of half a turn or a knee bent backwards, not style.
SPINE = {"swing": 60.0, "twist": 60.0}
RANGES = {"spine1": SPINE, "spine2": SPINE, "spine3": SPINE, "neck": {"swing": 90.0, "twist": 90.0},
          "left_collar": {"swing": 60.0, "twist": 60.0}, "right_collar": {"swing": 60.0, "twist": 60.0},
          "left_hip": {"swing": 150.0, "twist": 90.0}, "right_hip": {"swing": 150.0, "twist": 90.0},
          "left_shoulder": {"swing": 180.0, "twist": 120.0}, "right_shoulder": {"swing": 180.0, "twist": 120.0},
          "left_ankle": {"swing": 90.0, "twist": 60.0}, "right_ankle": {"swing": 90.0, "twist": 60.0}}
HINGES = {"left_knee": (np.array([1.0, 0, 0]), -15.0, 165.0), "right_knee": (np.array([1.0, 0, 0]), -15.0, 165.0),
          "left_elbow": (np.array([0, -1.0, 0]), -15.0, 165.0), "right_elbow": (np.array([0, 1.0, 0]), -15.0, 165.0)}
HINGE_OFF_AXIS = 30.0
STILL = 0.01  # m a frame at 30 fps: WHAM's "a foot that moves less than 1 cm a frame" (eval world)


def joint_errors(smpl: SmplMotion, joints: np.ndarray, feet: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Per mapped point, the distance (m, per frame) between forward kinematics and the world
    joints: ``skeleton.MAPPED``, the hips' midpoint, and the balls of the feet (with feet)."""
    out = {name: np.linalg.norm(smpl.joints[:, J[name]] - joints[:, h36m], axis=-1) for name, h36m in MAPPED.items()}
    out["hip_centre"] = np.linalg.norm((smpl.joints[:, 1] + smpl.joints[:, 2]) / 2 - (joints[:, 1] + joints[:, 4]) / 2,
                                       axis=-1)
    if feet is not None and np.isfinite(feet).all():
        for name, heel, toe in (("left_foot", 0, 2), ("right_foot", 1, 3)):
            ball = feet[:, heel] + BALL_SHARE * (feet[:, toe] - feet[:, heel])
            out[name] = np.linalg.norm(smpl.joints[:, J[name]] - ball, axis=-1)
    return out


# Each limb's bone as (SMPL parent, SMPL child) and (H36M parent, H36M child).
LIMB_BONES = {"left_upper_arm": ((16, 18), (11, 12)), "right_upper_arm": ((17, 19), (14, 15)),
              "left_forearm": ((18, 20), (12, 13)), "right_forearm": ((19, 21), (15, 16)),
              "left_thigh": ((1, 4), (4, 5)), "right_thigh": ((2, 5), (1, 2)),
              "left_shin": ((4, 7), (5, 6)), "right_shin": ((5, 8), (2, 3))}


def limb_directions(smpl: SmplMotion, joints: np.ndarray) -> dict[str, np.ndarray]:
    """Per limb, the angle (degrees, per frame) between the SMPL bone and the world bone: what a
    trainer sees of the arm's and leg's direction, whatever the two skeletons' bone lengths."""
    out = {}
    for name, ((a, b), (c, d)) in LIMB_BONES.items():
        mine, theirs = smpl.joints[:, b] - smpl.joints[:, a], joints[:, d] - joints[:, c]
        cos = (mine * theirs).sum(-1) / np.maximum(np.linalg.norm(mine, axis=-1) * np.linalg.norm(theirs, axis=-1),
                                                   1e-12)
        out[name] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def sliding(points: np.ndarray, planted: np.ndarray, fps: float) -> float:
    """Mean horizontal motion (mm per frame at 30 fps) of points (T x P x 3, y up) on the frames
    where each is planted (T x P) and on the frame before; NaN when none is."""
    step = np.linalg.norm(np.diff(points[..., [0, 2]], axis=0), axis=-1) * fps / 30.0
    held = planted[1:] & planted[:-1]
    return float(1000 * step[held].mean()) if held.any() else float("nan")


def foot_points(smpl: SmplMotion) -> np.ndarray:
    """T x 4 x 3 the SMPL ankles and feet (left ankle, right ankle, left foot, right foot)."""
    return smpl.joints[:, [J["left_ankle"], J["right_ankle"], J["left_foot"], J["right_foot"]]]


def world_foot_points(joints: np.ndarray, feet: np.ndarray | None) -> np.ndarray | None:
    """The same four points in the world file: its ankles and the balls of its feet."""
    if feet is None or not np.isfinite(feet).all():
        return None
    balls = [feet[:, h] + BALL_SHARE * (feet[:, t] - feet[:, h]) for h, t in ((0, 2), (1, 3))]
    return np.stack([joints[:, 6], joints[:, 3], *balls], axis=1)


def foot_planted(contact: np.ndarray, planted: np.ndarray | None) -> np.ndarray:
    """T x 4 which of the four foot points stand: an ankle with its foot's contact (or planted
    heel), a ball with its planted toe tip (or its foot's contact without the contact model)."""
    if planted is None:
        return np.concatenate([contact, contact], axis=1).astype(bool)
    return planted.astype(bool)  # heels stand for the ankles, toe tips for the balls: the same order


@dataclass(frozen=True)
class RangeReport:
    frames: int
    outside: dict[str, int]    # joint -> frames outside its range
    worst: dict[str, float]    # joint -> its largest angle (degrees): swing, twist or bend past a limit


def _swing_twist(local: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Swing and twist angles (degrees) of rotations (T x 3 x 3) about a unit bone ``axis``."""
    q = Rotation.from_matrix(local).as_quat()  # x, y, z, w
    along = q[:, :3] @ axis
    twist = np.degrees(2 * np.arctan2(np.abs(along), np.abs(q[:, 3])))
    total = np.degrees(Rotation.from_matrix(local).magnitude())
    swing = np.degrees(2 * np.arccos(np.clip(np.sqrt(q[:, 3] ** 2 + along ** 2), 0.0, 1.0)))
    return np.minimum(swing, total), twist


def joint_ranges(smpl: SmplMotion) -> RangeReport:
    """Frames on which a joint leaves its range (``RANGES``, ``HINGES``)."""
    children = {name: JOINTS[PARENTS.index(J[name])] for name in RANGES}  # each one's first child
    outside, worst = {}, {}
    for name, limits in RANGES.items():
        axis = REST_OFFSETS[J[children[name]]]
        swing, twist = _swing_twist(smpl.local[:, J[name]], axis / np.linalg.norm(axis))
        bad = (swing > limits["swing"]) | (twist > limits["twist"])
        outside[name], worst[name] = int(bad.sum()), round(float(max(swing.max(), twist.max())), 1)
    for name, (axis, low, high) in HINGES.items():
        rotvec = Rotation.from_matrix(smpl.local[:, J[name]]).as_rotvec()
        bend = np.degrees(rotvec @ axis)
        off = np.degrees(np.linalg.norm(rotvec - np.outer(rotvec @ axis, axis), axis=-1))
        bad = (bend < low) | (bend > high) | (off > HINGE_OFF_AXIS)
        outside[name], worst[name] = int(bad.sum()), round(float(min(bend.min(), 0.0)), 1)
    return RangeReport(len(smpl.local), outside, worst)

