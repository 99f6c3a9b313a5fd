"""Every dancer of a segment in one scene: one gravity, one floor, each where their planted feet meet it.

The dancers of a segment share the camera, and so its tilt and the floor below it. Each dancer's
path is first placed alone (the per-frame root anchored by the planted points,
``trajectory.refine_root``), and its planted points give a floor. Those floors differ in the scale
of each placement (a dancer whose body the lifter made 10 % too large looks 10 % too far, floor
and all), not in tilt: so the tilt is fitted to all dancers' planted points at once, each dancer's
plane parallel to the others' (``parallel_planes_up``: every dancer's spread adds to the tilt's
certainty), and the floor's level is the dancers' median. Every dancer is then scaled, pose and
path together (their image does not change), so that their own floor is the scene's, and placed
on it where their planted feet are seen (``grounding.ground_clip`` with the scene's frame); the
group's centre becomes the origin. A child lifted at an adult's size comes out child-sized, where
the child stands.

Assumed: a still camera (or one panning slowly: its tilt holds) and one flat floor. A dancer with
no planted point seen (no feet, never planted) shares the tilt and the floor but keeps their own
scale, which is then only as good as the lifter's body size; a floor that is not flat (stairs, a
stage and its front row) puts its dancers at the wrong depth.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pipeline.motion.world.contact import MIN_PLANTED_FRAMES, PLANTED_PROBABILITY, ContactRules, planted_points
from pipeline.motion.world.gravity import BODY_PRIOR, WorldFrame, camera_from_up, estimate_up
from pipeline.motion.world.grounding import GroundedClip, floor_level, ground_motion
from pipeline.motion.world.trajectory import refine_root


@dataclass(frozen=True)
class Scene:
    clips: list[GroundedClip]  # the segment's clips, in order, all in ``frame`` (y up, floor y = 0, group centre at 0)
    frame: WorldFrame
    scales: list[float]        # per clip: the factor that put its path on the scene's floor (1.0: not put on it)
    shared: bool = True        # False: no planted point was seen, each clip was grounded alone


@dataclass(frozen=True)
class _Placed:
    points: np.ndarray   # T x 4 x 3 heels and toe tips, root-relative, camera frame
    root: np.ndarray     # T x 3 the first refined root path
    anchors: np.ndarray  # T x 4 sure contacts


def _first_pass(clip, threshold: float, min_frames: int) -> _Placed | None:
    """A clip's path placed alone, when it has what the floor needs: feet, contacts seen, a root."""
    if clip.feet is None or clip.contact is None or clip.root is None or clip.feet_rays is None:
        return None
    anchors = planted_points(clip.contact, threshold, min_frames)
    if not anchors.any():
        return None
    points = clip.feet.astype(np.float64) - clip.joints[:, :1].astype(np.float64)
    return _Placed(points, refine_root(clip.root.astype(np.float64), points, anchors), anchors)


def parallel_planes_up(contacts: list[np.ndarray], body_up: np.ndarray, prior: float = BODY_PRIOR) -> np.ndarray:
    """The one normal (camera coordinates) of several parallel planes, one per dancer's planted
    points (``contacts``: per dancer N_i x 3): each dancer's scatter about their own centre, summed,
    so a dancer's unknown scale (which moves their plane, parallel to itself) does not count, and
    every dancer's spread adds to the tilt's certainty; pulled toward ``body_up`` as
    ``gravity.up_from_contacts`` is."""
    scatter = prior * (np.eye(3) - np.outer(body_up, body_up)) * len(contacts)
    for points in contacts:
        centred = points - points.mean(0)
        scatter = scatter + centred.T @ centred / len(centred)
    normal = np.linalg.eigh(scatter)[1][:, 0]
    return normal if normal @ body_up > 0 else -normal


def scene_frame(clips: list, *, threshold: float = PLANTED_PROBABILITY,
                min_frames: int = MIN_PLANTED_FRAMES) -> tuple[WorldFrame | None, list[float]]:
    """The scene's tilt and floor from its clips (``motionfile.MotionClip``), and each clip's scale
    onto that floor; None when no clip has planted points seen (nothing fixes a shared floor)."""
    placed = [_first_pass(c, threshold, min_frames) for c in clips]
    on_floor = [(c, p) for c, p in zip(clips, placed) if p is not None]
    if not on_floor:
        return None, [1.0] * len(clips)
    body_up = estimate_up(np.concatenate([c.joints.astype(np.float64) for c, _ in on_floor]))
    contacts = [(p.root[:, None] + p.points)[p.anchors] for _, p in on_floor]
    up = parallel_planes_up(contacts, body_up)
    levels = np.array([floor_level(x, up) for x in contacts])
    floor = float(np.median(levels))
    each = iter(floor / levels)
    return WorldFrame(camera_from_up(up), floor), [float(next(each)) if p is not None else 1.0 for p in placed]


def scaled(clip, k: float):
    """A motion clip with its pose and path ``k`` times as large: the same image, nearer or further."""
    if k == 1.0:
        return clip
    k32 = np.float32(k)
    return replace(clip, joints=clip.joints * k32, root=None if clip.root is None else clip.root * k32,
                   feet=None if clip.feet is None else clip.feet * k32)


def ground_scene(clips: list, fps: float, rules: ContactRules = ContactRules()) -> Scene:
    """Every clip of a segment (``motionfile.MotionClip``) grounded in one frame (module docstring)
    with the contact ``rules``. Without any planted point seen, each clip is grounded alone and the
    scene is theirs side by side (its ``frame`` is the first clip's)."""
    frame, scales = scene_frame(clips, threshold=rules.threshold, min_frames=rules.min_frames)
    grounded = [ground_motion(scaled(c, k), fps, rules, frame=frame) for c, k in zip(clips, scales)]
    if frame is None:
        first = grounded[0].camera if grounded else camera_from_up(np.array([0.0, -1.0, 0.0]))
        return Scene(grounded, WorldFrame(first, 0.0), scales, shared=False)
    centre = np.concatenate([g.joints[:, 0] for g in grounded]).mean(0) * [1.0, 0.0, 1.0]
    moved = [replace(g, joints=g.joints - centre, feet=None if g.feet is None else g.feet - centre)
             for g in grounded]
    return Scene(moved, replace(frame, origin=frame.origin + centre), scales)


def ground_in_scene(clips: list, clip_id: str, fps: float, rules: ContactRules = ContactRules()) -> GroundedClip:
    """One clip as the corpus has it: grounded in the scene of all the clips of its segment."""
    ids = [c.clip_id for c in clips]
    return ground_scene(clips, fps, rules).clips[ids.index(clip_id)]
