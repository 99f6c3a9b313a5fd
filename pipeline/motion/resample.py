"""Cubic-spline resampling of motion to exactly the corpus rate (``common.fps``, 24 by default).

Frame k of the output lies at ``k / fps`` seconds on the segment's clock (the same grid
as the audio features); a clip covers the grid points from its first to its last source
frame, with no extrapolation. A not-a-knot cubic spline reproduces cubic polynomials
exactly, so smooth motion is not distorted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

TARGET_FPS = 24  # the default corpus rate


def grid_frames(t_first: float, t_last: float, fps: float = TARGET_FPS) -> np.ndarray:
    """Integer frame numbers k with t_first <= k / fps <= t_last (a hair of tolerance)."""
    first = math.ceil(t_first * fps - 1e-6)
    last = math.floor(t_last * fps + 1e-6)
    return np.arange(first, last + 1, dtype=np.int64)


def interpolate_linear(at: np.ndarray, times: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` (T x ...) given at ``times``, linearly interpolated at ``at``, every channel apart
    (held at the ends)."""
    flat = np.asarray(values).reshape(len(values), -1)
    out = np.stack([np.interp(at, times, flat[:, c]) for c in range(flat.shape[1])], -1)
    return out.reshape((len(at),) + np.shape(values)[1:])


def resample_cubic(times: np.ndarray, values: np.ndarray, fps: float = TARGET_FPS) -> tuple[np.ndarray, np.ndarray]:
    """Resample ``values`` (T x ...) given at ``times`` to the ``fps`` grid: (frame numbers, values)."""
    frames = grid_frames(float(times[0]), float(times[-1]), fps)
    new_times = np.clip(frames / fps, times[0], times[-1])
    if len(times) < 4:  # too short for a cubic: linear
        return frames, interpolate_linear(new_times, times, values)
    spline = CubicSpline(times, values, axis=0, bc_type="not-a-knot")
    return frames, spline(new_times)


# --- the resample stage's worker ---------------------------------------------------------

@dataclass(frozen=True)
class ResampleJob:
    smooth: Path
    out: Path
    fps: float
    params: dict
    inputs: dict
    fingerprint: str


def resample_clip(clip, fps: float):
    """A motion clip on the ``fps`` grid (None when no grid point falls inside it): cubic for the
    motion (hands too), linear for the contact probabilities and the hands' presence (a spline would
    overshoot 0 and 1) and the sight rays."""
    from pipeline.motion.motionfile import MotionClip

    frames, joints = resample_cubic(clip.time, clip.joints, fps)
    if not len(frames):
        return None
    near = np.clip(np.searchsorted(clip.time, frames / fps), 0, len(clip.time) - 1)
    root = None if clip.root is None else resample_cubic(clip.time, clip.root, fps)[1].astype(np.float32)
    feet = None if clip.feet is None else resample_cubic(clip.time, clip.feet, fps)[1].astype(np.float32)
    at = np.clip(frames / fps, clip.time[0], clip.time[-1])
    contact = None if clip.contact is None else interpolate_linear(at, clip.time, clip.contact).astype(np.float32)
    rays = None
    if clip.feet_rays is not None:  # directions: between the two, then of unit length again
        rays = interpolate_linear(at, clip.time, clip.feet_rays)
        rays = (rays / np.linalg.norm(rays, axis=-1, keepdims=True)).astype(np.float32)
    hands = None if clip.hands is None else resample_cubic(clip.time, clip.hands, fps)[1].astype(np.float32)
    presence = (None if clip.hand_presence is None
                else interpolate_linear(at, clip.time, clip.hand_presence).astype(np.float32))
    return MotionClip(clip.clip_id, clip.track_id, frames, frames / fps, joints.astype(np.float32),
                      clip.interpolated[near], clip.filled_joints[near], root, feet, contact, rays, hands, presence)


def resample_segment(job: ResampleJob) -> dict:
    from pipeline.motion.motionfile import read_motion, write_motion

    motion = read_motion(job.smooth)
    clips = [c for c in (resample_clip(clip, job.fps) for clip in motion.clips) if c is not None]
    segment = {"fps": job.fps, "source_fps": motion.meta.get("fps"),
               **{k: motion.meta.get(k) for k in ("segment_id", "width", "height")}}
    write_motion(job.out, clips, segment, fingerprint=job.fingerprint, params=job.params, inputs=job.inputs)
    return {"clips": len(clips)}
