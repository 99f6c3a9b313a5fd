"""Foot contact and foot sliding, for world-frame motion (y up, floor at y = 0).

A foot is in contact when its ankle is near the floor and barely moves horizontally. Skating
is the horizontal ankle speed while in contact (a planted foot does not slide). ``pin_feet``
holds each contact's foot where it landed, bending the leg with two-bone inverse kinematics
(thigh and shin keep their lengths; the knee stays in its own bending plane), easing in and
out over a few frames. With heels and toe tips (a lifter with feet) contact is judged at the
foot's lower point, heel or toe, so a foot on its ball or its heel stands too (the corpus keeps
the ankle rule: on lifted motion the feet rule scored no better, docs/reports/world.md); the feet ride on
their ankles when legs are bent. Skating stays measured at the ankles (comparable either way).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from pipeline.motion.mocap.skeleton import FEET_ANKLES_H36M
from pipeline.motion.world.gravity import ANKLE_HEIGHT, FOOT_POINT_HEIGHT

ANKLES = (6, 3)                      # H36M left ankle, right ankle
LEGS = ((4, 5, 6), (1, 2, 3))        # hip, knee, ankle: left, right
FOOT_POINTS = ((0, 2), (1, 3))       # heel, toe tip (in skeleton.FEET): left, right


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def _drop_short(flags: np.ndarray, min_frames: int) -> np.ndarray:
    """T x K flags with every run shorter than ``min_frames`` frames cleared (a blip is not a step)."""
    for k in range(flags.shape[1]):
        for a, b in _runs(flags[:, k]):
            if b - a < min_frames:
                flags[a:b, k] = False
    return flags


def _ease(n: int, a: int, b: int, ease: int) -> tuple[int, int, np.ndarray]:
    """The frames ``lo:hi`` a contact ``a:b`` acts on, and its weight there: 1 inside, ramping over
    ``ease`` frames on either side."""
    lo, hi = max(0, a - ease), min(n, b + ease)
    ramp = np.ones(hi - lo)
    ramp[: a - lo] = np.arange(1, a - lo + 1) / (a - lo + 1)
    ramp[len(ramp) - (hi - b):] = np.arange(hi - b, 0, -1) / (hi - b + 1)
    return lo, hi, ramp


def _leg_lengths(world: np.ndarray, hip: int, knee: int, ankle: int) -> tuple[float, float]:
    """The clip's median thigh and shin lengths."""
    return (float(np.median(np.linalg.norm(world[:, knee] - world[:, hip], axis=-1))),
            float(np.median(np.linalg.norm(world[:, ankle] - world[:, knee], axis=-1))))


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
    return _drop_short(low & (moving < speed), min_frames)


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
        thigh, shin = _leg_lengths(world, hip, knee, ankle)
        target = world[:, ankle].copy()
        weight = np.zeros(len(world))
        for a, b in _runs(contact[:, foot]):
            anchor = np.median(world[a:b, ankle][:, [0, 2]], axis=0)
            lo, hi, ramp = _ease(len(world), a, b, ease)
            target[lo:hi, 0], target[lo:hi, 2] = anchor[0], anchor[1]
            weight[lo:hi] = np.maximum(weight[lo:hi], ramp)
        goal = world[:, ankle] + weight[:, None] * (target - world[:, ankle])
        moved = weight > 0
        if moved.any():
            new_knee, new_ankle = _two_bone(world[moved, hip], world[moved, knee], goal[moved], thigh, shin)
            out[moved, knee], out[moved, ankle] = new_knee, new_ankle
    return out


# Chosen on training sequences (contact F1 of the whole world path, `dance3d eval world --all` on 40
# of them: 0.925 at 0.25, 0.930 at 0.3, 0.933 at 0.35 and 0.4, 0.929 at 0.5), never on held-out ones.
PLANTED_PROBABILITY = 0.4
MIN_PLANTED_FRAMES = 3
HOLD_PROBABILITY = 0.1


@dataclass(frozen=True)
class ContactRules:
    """When contact probabilities make a heel or toe tip planted (params.yaml ``ground``): what the
    ground stage does, and what ``dance3d eval world``, ``eval group``, render and export run."""
    threshold: float = PLANTED_PROBABILITY  # planted above this probability ...
    min_frames: int = MIN_PLANTED_FRAMES    # ... for at least this many frames in a row (corpus rate) ...
    hold: float = HOLD_PROBABILITY          # ... and while above this one (hysteresis)

    @classmethod
    def from_params(cls, ground: Mapping) -> ContactRules:
        return cls(float(ground.get("contact_threshold", cls.threshold)),
                   int(ground.get("min_contact_frames", cls.min_frames)),
                   float(ground.get("contact_hold", cls.hold)))


def planted_points(probability: np.ndarray, threshold: float = PLANTED_PROBABILITY,
                   min_frames: int = MIN_PLANTED_FRAMES, hold: float | None = None) -> np.ndarray:
    """T x 4 planted flags from contact probabilities (heels and toe tips): above ``threshold``
    for at least ``min_frames`` frames in a row (a single frame is noise, not a step). With
    ``hold`` (hysteresis, as in Canny's edges), a contact so found lasts for as long as the
    probability stays above ``hold`` on either side: the model is late to call a landing and early
    to call a lift-off, and a foot freed too early slides where it still stands."""
    core = _drop_short(np.asarray(probability) > threshold, min_frames)
    return held_contacts(core, probability, hold, threshold)


def held_contacts(core: np.ndarray, probability: np.ndarray, hold: float | None, threshold: float) -> np.ndarray:
    """T x K flags: each run of ``probability`` above ``hold`` that holds a ``core`` contact (found
    above ``threshold``), whole: ``planted_points``' hysteresis for contacts already found; ``core``
    as it is without a hold below the threshold."""
    if hold is None or hold >= threshold:
        return core
    probability = np.asarray(probability)
    out = np.zeros_like(core)
    for k in range(core.shape[1]):
        for a, b in _runs(probability[:, k] > hold):
            out[a:b, k] = core[a:b, k].any()
    return out


def foot_planted(planted: np.ndarray) -> np.ndarray:
    """T x 2 (left, right): a foot is on the floor when its heel or its toe tip is planted."""
    return np.stack([planted[:, list(points)].any(1) for points in FOOT_POINTS], 1)


def pin_planted(world: np.ndarray, feet: np.ndarray, planted: np.ndarray,
                ease: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """World joints (T x 17 x 3) and feet (T x 4 x 3) with every planted heel or toe tip held where
    it stands during its contact and on the floor (y = 0): the ankle is moved by the planted points'
    mean offset from their targets and the leg bent to reach it by two-bone IK; the feet ride on
    their ankles. Each contact eases in and out over ``ease`` frames."""
    out = world.copy()
    n = len(world)
    for side, (hip, knee, ankle) in enumerate(LEGS):
        points = list(FOOT_POINTS[side])
        thigh, shin = _leg_lengths(world, hip, knee, ankle)
        shift = np.zeros((n, 3))
        weight = np.zeros(n)
        for a, b in _runs(planted[:, points].any(1)):
            offsets = np.zeros((b - a, 3))
            count = np.zeros(b - a)
            for p in points:
                mask = planted[a:b, p]
                if not mask.any():
                    continue
                target = np.median(feet[a:b, p][mask], axis=0)
                target[1] = 0.0
                offsets[mask] += target - feet[a:b, p][mask]
                count[mask] += 1
            offsets /= np.maximum(count, 1)[:, None]
            lo, hi, ramp = _ease(n, a, b, ease)
            shift[a:b] = offsets
            shift[lo:a], shift[b:hi] = offsets[0], offsets[-1]
            weight[lo:hi] = np.maximum(weight[lo:hi], ramp)
        moved = weight > 0
        if moved.any():
            goal = world[moved, ankle] + weight[moved, None] * shift[moved]
            out[moved, knee], out[moved, ankle] = _two_bone(world[moved, hip], world[moved, knee], goal, thigh, shin)
    carried = carry_feet(feet, world, out)
    # A planted point stands exactly on its target: the foot's own shape jitters in the lifted
    # motion, and moving the ankle alone would leave each point sliding by that jitter.
    for k in range(feet.shape[1]):
        for a, b in _runs(planted[:, k]):
            target = np.median(feet[a:b, k], axis=0)
            target[1] = 0.0
            carried[a:b, k] = target
    return out, carried


def carry_feet(feet: np.ndarray, before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Heels and toes (T x 4 x 3) moved with their ankles from the joints ``before`` to ``after``."""
    ankles = list(FEET_ANKLES_H36M)
    return feet + (after[:, ankles] - before[:, ankles])


# --- the label rule on motion capture: what "planted" means for the learned contacts ---------

CAPTURE_SPEED = 0.2    # m/s: GVHMR's static joints are < 0.15 m/s, WHAM's ~1 cm per frame at 30 fps (0.3)
CAPTURE_HEIGHT = 0.04  # m above the standing level: a planted point, not one lifted for a step


def standing_level(feet: np.ndarray, fps: float, speed: float = CAPTURE_SPEED) -> float:
    """Height of the floor's contact level in world motion (T x 4 x 3 heels and toe tips, y up): the
    median height of the lowest foot point over the frames where it is still. Rigs differ in where
    their floor is and some feet pass below it, so the level is measured, not assumed to be y = 0."""
    speeds = np.linalg.norm(np.gradient(feet, axis=0), axis=-1) * fps
    lowest = feet[..., 1].argmin(1)
    heights = feet[np.arange(len(feet)), lowest, 1]
    still = speeds[np.arange(len(feet)), lowest] < speed
    return float(np.median(heights[still]) if still.sum() >= 10 else np.percentile(heights, 5))


def capture_contact(feet: np.ndarray, fps: float, level: float | None = None) -> np.ndarray:
    """T x 4 contact flags of world heels and toe tips (``skeleton.FEET`` order) from motion capture:
    a point is planted when it is within ``CAPTURE_HEIGHT`` of the standing level and moves (in 3D)
    slower than ``CAPTURE_SPEED``. Heel and toe apart, so a dancer on the ball of the foot is planted
    at the toe and a heel pivot at the heel."""
    level = standing_level(feet, fps) if level is None else level
    speeds = np.linalg.norm(np.gradient(feet, axis=0), axis=-1) * fps
    return (feet[..., 1] - level < CAPTURE_HEIGHT) & (speeds < CAPTURE_SPEED)
