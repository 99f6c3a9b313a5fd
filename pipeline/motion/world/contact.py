"""Foot contact and foot sliding, for world-frame motion (y up, floor at y = 0).

A foot is in contact when its ankle is near the floor and barely moves horizontally. Skating
is the horizontal ankle speed while in contact (a planted foot does not slide). ``pin_feet``
holds each contact's foot where it landed, bending the leg with two-bone inverse kinematics
(thigh and shin keep their lengths; the knee stays in its own bending plane), easing in and
out over a few frames. With heels and toe tips (a lifter with feet) contact is judged at the
foot's lower point, heel or toe, so a foot on its ball or its heel stands too (the corpus keeps
the ankle rule: on lifted motion the feet rule scored no better, README); the feet ride on
their ankles when legs are bent. Skating stays measured at the ankles (comparable either way).
"""

from __future__ import annotations

import numpy as np

from pipeline.motion.mocap.skeleton import FEET_ANKLES_H36M
from pipeline.motion.world.gravity import ANKLE_HEIGHT, FOOT_POINT_HEIGHT

ANKLES = (6, 3)                      # H36M left ankle, right ankle
LEGS = ((4, 5, 6), (1, 2, 3))        # hip, knee, ankle: left, right
FOOT_POINTS = ((0, 2), (1, 3))       # heel, toe tip (in skeleton.FEET): left, right


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def horizontal_speed(world: np.ndarray, fps: float) -> np.ndarray:
    """T x 2 horizontal ankle speeds (m/s), left and right."""
    xz = world[:, list(ANKLES)][..., [0, 2]]
    return np.linalg.norm(np.gradient(xz, axis=0), axis=-1) * fps


def foot_contact(world: np.ndarray, fps: float, height: float = 0.10, speed: float = 0.3,
                 min_frames: int = 3, feet: np.ndarray | None = None, feet_height: float = 0.05) -> np.ndarray:
    """T x 2 contact flags (left, right): ankle within ``height`` m of its resting height (10 cm:
    a dancer on the ball of the foot is still standing) and moving slower than ``speed`` m/s
    horizontally, for at least ``min_frames`` frames. With ``feet`` (T x 4 x 3 world heels and
    toe tips): the foot's lower point within ``feet_height`` of its resting height, and slow."""
    if feet is None:
        low = world[:, list(ANKLES), 1] < ANKLE_HEIGHT + height
        moving = horizontal_speed(world, fps)
    else:
        pick = np.stack([feet[:, list(points)] for points in FOOT_POINTS], 1)  # T x 2 sides x 2 points x 3
        lower = np.argmin(pick[..., 1], axis=-1)
        point = np.take_along_axis(pick, lower[..., None, None], axis=2)[:, :, 0]  # T x 2 x 3
        low = point[..., 1] < FOOT_POINT_HEIGHT + feet_height
        moving = np.linalg.norm(np.gradient(point[..., [0, 2]], axis=0), axis=-1) * fps
    contact = low & (moving < speed)
    for foot in range(2):
        for a, b in _runs(contact[:, foot]):
            if b - a < min_frames:
                contact[a:b, foot] = False
    return contact


def skating(world: np.ndarray, contact: np.ndarray, fps: float) -> float:
    """Mean horizontal ankle speed (m/s) over the frames a foot is in contact (NaN without contact)."""
    speeds = horizontal_speed(world, fps)
    return float(speeds[contact].mean()) if contact.any() else float("nan")


def _two_bone(hip: np.ndarray, knee: np.ndarray, target: np.ndarray, thigh: float, shin: float) -> tuple:
    """Knee and ankle (T x 3) reaching ``target`` from ``hip`` with fixed bone lengths, the knee
    on the side it was on (its bending plane kept)."""
    to_target = target - hip
    d = np.clip(np.linalg.norm(to_target, axis=-1), abs(thigh - shin) + 1e-6, thigh + shin - 1e-6)
    u = to_target / np.maximum(np.linalg.norm(to_target, axis=-1, keepdims=True), 1e-9)
    pole = (knee - hip) - ((knee - hip) * u).sum(-1, keepdims=True) * u
    pole = pole / np.maximum(np.linalg.norm(pole, axis=-1, keepdims=True), 1e-9)
    cos_a = np.clip((thigh ** 2 + d ** 2 - shin ** 2) / (2 * thigh * d), -1.0, 1.0)
    new_knee = hip + thigh * (cos_a[:, None] * u + np.sqrt(1 - cos_a ** 2)[:, None] * pole)
    return new_knee, hip + d[:, None] * u


def pin_feet(world: np.ndarray, contact: np.ndarray, ease: int = 3) -> np.ndarray:
    """World motion with each contact's ankle held at the contact's median horizontal position."""
    out = world.copy()
    for foot, (hip, knee, ankle) in enumerate(LEGS):
        thigh = float(np.median(np.linalg.norm(world[:, knee] - world[:, hip], axis=-1)))
        shin = float(np.median(np.linalg.norm(world[:, ankle] - world[:, knee], axis=-1)))
        target = world[:, ankle].copy()
        weight = np.zeros(len(world))
        for a, b in _runs(contact[:, foot]):
            anchor = np.median(world[a:b, ankle][:, [0, 2]], axis=0)
            lo, hi = max(0, a - ease), min(len(world), b + ease)
            target[lo:hi, 0], target[lo:hi, 2] = anchor[0], anchor[1]
            ramp = np.ones(hi - lo)
            ramp[: a - lo] = np.arange(1, a - lo + 1) / (a - lo + 1)
            ramp[len(ramp) - (hi - b):] = np.arange(hi - b, 0, -1) / (hi - b + 1)
            weight[lo:hi] = np.maximum(weight[lo:hi], ramp)
        goal = world[:, ankle] + weight[:, None] * (target - world[:, ankle])
        moved = weight > 0
        if moved.any():
            new_knee, new_ankle = _two_bone(world[moved, hip], world[moved, knee], goal[moved], thigh, shin)
            out[moved, knee], out[moved, ankle] = new_knee, new_ankle
    return out


def carry_feet(feet: np.ndarray, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Heels and toes (T x 4 x 3) moved with their ankles from the joints ``before`` to ``after``."""
    ankles = list(FEET_ANKLES_H36M)
    return feet + (after[:, ankles] - before[:, ankles])
