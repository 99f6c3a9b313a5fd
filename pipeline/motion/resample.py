"""Cubic-spline resampling of motion to exactly 24 fps on the segment clock.

Frame k of the output lies at ``k / 24`` seconds on the segment's clock (the same grid
as the audio features); a clip covers the grid points from its first to its last source
frame, with no extrapolation. A not-a-knot cubic spline reproduces cubic polynomials
exactly, so smooth motion is not distorted.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicSpline

TARGET_FPS = 24


def grid_frames(t_first: float, t_last: float, fps: int = TARGET_FPS) -> np.ndarray:
    """Integer frame numbers k with t_first <= k / fps <= t_last (a hair of tolerance)."""
    first = math.ceil(t_first * fps - 1e-6)
    last = math.floor(t_last * fps + 1e-6)
    return np.arange(first, last + 1, dtype=np.int64)


def resample_cubic(times: np.ndarray, values: np.ndarray, fps: int = TARGET_FPS) -> tuple[np.ndarray, np.ndarray]:
    """Resample ``values`` (T x ...) given at ``times`` to the ``fps`` grid: (frame numbers, values)."""
    frames = grid_frames(float(times[0]), float(times[-1]), fps)
    new_times = np.clip(frames / fps, times[0], times[-1])
    if len(times) < 4:  # too short for a cubic: linear
        flat = values.reshape(len(values), -1)
        out = np.column_stack([np.interp(new_times, times, flat[:, c]) for c in range(flat.shape[1])])
        return frames, out.reshape((len(frames),) + values.shape[1:])
    spline = CubicSpline(times, values, axis=0, bc_type="not-a-knot")
    return frames, spline(new_times)
