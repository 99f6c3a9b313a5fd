"""Joint orders and the construction of COCO-17 keypoints (face points included) from a body."""

from __future__ import annotations

import numpy as np

from pipeline.pose.pose2dfile import FOOT_POINTS

H36M17 = ("pelvis", "right_hip", "right_knee", "right_ankle", "left_hip", "left_knee", "left_ankle", "spine",
          "thorax", "neck_nose", "head", "left_shoulder", "left_elbow", "left_wrist", "right_shoulder",
          "right_elbow", "right_wrist")
# Bones of the H36M skeleton (parent, child), used for bone-length checks and drawing.
H36M_BONES = ((0, 1), (1, 2), (2, 3), (0, 4), (4, 5), (5, 6), (0, 7), (7, 8), (8, 9), (9, 10), (8, 11), (11, 12),
              (12, 13), (8, 14), (14, 15), (15, 16))
H36M_FLIP = (0, 4, 5, 6, 1, 2, 3, 7, 8, 9, 10, 14, 15, 16, 11, 12, 13)
COCO_FLIP = (0, 2, 1, 4, 3, 6, 5, 8, 7, 10, 9, 12, 11, 14, 13, 16, 15)
# Left and right bones as index pairs into H36M_BONES: hip, thigh, shin, shoulder, upper arm, forearm.
H36M_BONE_PAIRS = ((3, 0), (4, 1), (5, 2), (10, 13), (11, 14), (12, 15))
# (COCO index, H36M index) of the body joints both skeletons have: shoulders, elbows, wrists, hips
# (COCO's sit a little wider), knees, ankles.
COCO_H36M_SHARED = ((5, 11), (6, 14), (7, 12), (8, 15), (9, 13), (10, 16), (11, 4), (12, 1), (13, 5), (14, 2),
                    (15, 6), (16, 3))
WORLD_UP = np.array([0.0, 1.0, 0.0])

# The feet, appended after the 17 body joints in 2D (COCO-17 + 4) and 3D (H36M-17 + 4), in the
# 2D stage's order (FOOT_POINTS: left heel, right heel, left toe, right toe). The toe is the tip of the
# toes, BlazePose's "foot index".
FEET_FLIP = (1, 0, 3, 2)
FEET_ANKLES_H36M = (6, 3, 6, 3)     # the ankle of each foot point, in H36M-17
FEET_ANKLES_COCO = (15, 16, 15, 16)  # ... in COCO-17
H36M21 = H36M17 + FOOT_POINTS
# Each foot drawn as a triangle: ankle-heel, ankle-toe, heel-toe (indices into the 21 joints).
FOOT_BONES = ((6, 17), (6, 19), (17, 19), (3, 18), (3, 20), (18, 20))
COCO21_FLIP = COCO_FLIP + tuple(17 + i for i in FEET_FLIP)
H36M21_FLIP = H36M_FLIP + tuple(17 + i for i in FEET_FLIP)
# A standing adult's foot in the sagittal plane, ankle centre at the origin, x forward, y up, in
# shares of stature (Drillis & Contini's segment proportions: ankle height 0.039, foot length 0.152;
# the ankle a quarter of the foot from the heel, the ball at 72 % of it). Sole points sit 4 mm above
# the floor, as skin markers and a pose model's heel do.
FOOT_TEMPLATE = {"heel": (-0.038, -0.037), "ball": (0.071, -0.037), "tip": (0.114, -0.037)}
FOOT_TEMPLATE_FLOOR = -0.039  # the floor below the ankle, share of stature


def unit(v: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) scaled to length 1 (a zero vector stays zero)."""
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def smallest_rotation(rest: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """T x 3 x 3: the smallest rotations taking the unit vector ``rest`` to each unit ``targets[t]``
    (half a turn about an axis square to ``rest`` when they are opposite)."""
    from scipy.spatial.transform import Rotation

    v = np.cross(rest, targets)
    s = np.linalg.norm(v, axis=-1)
    c = np.clip((targets * rest).sum(-1), -1.0, 1.0)
    square = unit(np.cross(rest, [0.0, 1.0, 0.0] if abs(rest[1]) < 0.9 else [1.0, 0.0, 0.0]))
    axis = np.where(s[:, None] > 1e-9, v / np.maximum(s, 1e-12)[:, None], square[None])
    return Rotation.from_rotvec(axis * np.arctan2(s, c)[:, None]).as_matrix()


def head_frame(h36m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame head axes (up, forward, left) from the body: up = thorax->head joint,
    forward = horizontal facing from the hips ((left_hip - right_hip) x world up)."""
    up = unit(h36m[:, 9] - h36m[:, 8])
    facing = np.cross(h36m[:, 4] - h36m[:, 1], WORLD_UP)
    facing[:, 1] = 0.0
    forward = unit(facing - (facing * up).sum(-1, keepdims=True) * up)
    left = np.cross(up, forward)
    return up, forward, left


def stature(h36m: np.ndarray) -> float:
    """Standing height estimate (m): median head-joint-to-ankles distance x 1.08."""
    ankles = (h36m[:, 3] + h36m[:, 6]) / 2
    return float(np.median(np.linalg.norm(h36m[:, 9] - ankles, axis=-1)) * 1.08)


def leg_stature(h36m: np.ndarray) -> float:
    """Standing height estimate (m) from the legs: thigh + shank is 0.491 of stature (Drillis &
    Contini), median over frames and sides. Unlike ``stature`` it needs no head joint convention."""
    legs = [np.linalg.norm(h36m[:, hip] - h36m[:, knee], axis=-1) + np.linalg.norm(h36m[:, knee] - h36m[:, ankle],
                                                                                     axis=-1)
            for hip, knee, ankle in ((1, 2, 3), (4, 5, 6))]
    return float(np.median(np.concatenate(legs)) / 0.491)


def head_top(h36m: np.ndarray, height_share: float = 0.10) -> np.ndarray:
    """Head top when the rig has none: head joint + share x stature along the head's up axis."""
    up, _, _ = head_frame(h36m)
    return h36m[:, 9] + height_share * stature(h36m) * up


def foot_points(knee: np.ndarray, ankle: np.ndarray, point: np.ndarray, kind: str, stature_m: float,
                floor: float | None = None) -> dict[str, np.ndarray]:
    """Heel, ball and toe tip (each T x 3) of a foot known by its ankle and one point of the
    front of the foot (``kind``: "ball" or "tip"), from ``FOOT_TEMPLATE``: the template is
    turned in the plane of the shank and the foot until its ``kind`` point lies on the ankle ->
    ``point`` line, and scaled by stature. The toes go on in line with the foot, except that
    with a ``floor`` height they bend up rather than pass below the sole (a foot on its ball)."""
    forward = unit(point - ankle)
    up = unit((knee - ankle) - ((knee - ankle) * forward).sum(-1, keepdims=True) * forward)
    anchor = np.arctan2(FOOT_TEMPLATE[kind][1], FOOT_TEMPLATE[kind][0])
    out = {}
    for name, (x, y) in FOOT_TEMPLATE.items():
        angle, radius = np.arctan2(y, x) - anchor, np.hypot(x, y) * stature_m
        out[name] = ankle + radius * (np.cos(angle) * forward + np.sin(angle) * up)
    if floor is not None:
        sole = sole_height(floor, stature_m)
        ball, toes = out["ball"], out["tip"] - out["ball"]
        length = np.linalg.norm(toes, axis=-1, keepdims=True)
        drop = np.clip(ball[:, 1:2] - sole, 0.0, length)
        bent = ball + unit(toes * [1.0, 0.0, 1.0]) * np.sqrt(length ** 2 - drop ** 2) - drop * [0.0, 1.0, 0.0]
        out["tip"] = np.where(out["tip"][:, 1:2] < sole, bent, out["tip"])
    return out


def sole_height(floor: float, stature_m: float) -> float:
    """The height of the template's sole points (heel, ball, toe tip) standing on ``floor``."""
    return floor + (FOOT_TEMPLATE["heel"][1] - FOOT_TEMPLATE_FLOOR) * stature_m


def floor_height(points: np.ndarray) -> float:
    """A capture's floor: the 2nd percentile of the heights of ``points`` (..., 3), its lowest foot points."""
    return float(np.percentile(points[..., 1], 2))


def feet_array(heels: tuple[np.ndarray, np.ndarray], tips: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """T x 4 x 3 in ``FOOT_POINTS`` order from (left, right) heels and (left, right) toe tips."""
    return np.stack([heels[0], heels[1], tips[0], tips[1]], axis=1)


HIP_WIDENING = 1.1  # COCO's hip keypoints sit wider than the hip joint centres


def coco_from_h36m(h36m: np.ndarray, hip_widening: float = HIP_WIDENING) -> np.ndarray:
    """COCO-17 keypoints (T x 17 x 3) from H36M-17 joints: body joints shared, hips a little
    wider (COCO hips sit wider than joint centres), face placed from the head joint."""
    up, forward, left = head_frame(h36m)
    s = stature(h36m)
    c = h36m[:, 9]
    coco = np.zeros_like(h36m)
    coco[:, 0] = c + 0.03 * s * up + 0.06 * s * forward
    coco[:, 1] = c + 0.04 * s * up + 0.05 * s * forward + 0.019 * s * left
    coco[:, 2] = c + 0.04 * s * up + 0.05 * s * forward - 0.019 * s * left
    coco[:, 3] = c + 0.02 * s * up + 0.045 * s * left
    coco[:, 4] = c + 0.02 * s * up - 0.045 * s * left
    for coco_i, h_i in COCO_H36M_SHARED:
        coco[:, coco_i] = h36m[:, h_i]
    pelvis = h36m[:, 0]
    coco[:, 11] = pelvis + hip_widening * (h36m[:, 4] - pelvis)
    coco[:, 12] = pelvis + hip_widening * (h36m[:, 1] - pelvis)
    return coco


def bone_lengths(h36m: np.ndarray) -> np.ndarray:
    """T x 16 bone lengths."""
    return np.stack([np.linalg.norm(h36m[:, b] - h36m[:, a], axis=-1) for a, b in H36M_BONES], -1)
