"""The Hodrick-Prescott filter, solved for many series at once.

The HP trend tau of a series y minimises ||y - tau||^2 + lambda ||D tau||^2 with D the
second-difference operator, i.e. (I + lambda D'D) tau = y. The matrix is symmetric,
positive definite and pentadiagonal: its banded Cholesky factor (scipy, cached per length
and lambda) is computed once, and LAPACK's banded solve takes every joint coordinate of a clip
as one right-hand side each, instead of one sparse solve per series
(``statsmodels.tsa.filters.hp_filter.hpfilter``, the reference in the tests).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded


def hp_banded(n: int, lamb: float) -> np.ndarray:
    """Upper banded form (3 x n) of I + lambda D'D (``scipy.linalg.cholesky_banded``'s layout)."""
    main = np.full(n, 1.0 + 6.0 * lamb)
    main[[0, -1]] = 1.0 + lamb
    main[[1, -2]] = 1.0 + 5.0 * lamb
    first = np.full(n - 1, -4.0 * lamb)
    first[[0, -1]] = -2.0 * lamb
    second = np.full(n - 2, lamb)
    ab = np.zeros((3, n))
    ab[0, 2:] = second
    ab[1, 1:] = first
    ab[2, :] = main
    return ab


@lru_cache(maxsize=64)
def _factor(n: int, lamb: float) -> np.ndarray:
    """Upper banded Cholesky factor U (A = U'U), as ``cho_solve_banded`` takes it."""
    factor = cholesky_banded(hp_banded(n, lamb), lower=False, check_finite=False)
    factor.setflags(write=False)
    return factor


def hp_lambda_at(lamb: float, fps: float, reference_fps: float) -> float:
    """The HP lambda at ``fps`` that passes the same frequencies (Hz) as ``lamb`` does at
    ``reference_fps``: lambda scales with the fourth power of the sampling rate (Ravn and Uhlig, 2002)."""
    return float(lamb) * (float(fps) / float(reference_fps)) ** 4


def hp_trend(series: np.ndarray, lamb: float = 1.0) -> np.ndarray:
    """HP trend along axis 0 of ``series`` (T x ...), every other axis a separate series."""
    y = np.asarray(series, dtype=np.float64)
    n = y.shape[0]
    if n < 3 or lamb == 0:
        return y.copy()
    if n == 3:  # the band formulas above assume n >= 4
        d = np.array([[1.0, -2.0, 1.0]])
        return np.linalg.solve(np.eye(3) + lamb * d.T @ d, y.reshape(3, -1)).reshape(y.shape)
    flat = np.ascontiguousarray(y.reshape(n, -1))
    return cho_solve_banded((_factor(n, float(lamb)), False), flat, check_finite=False).reshape(y.shape)


# --- the smooth stage's worker -----------------------------------------------------------

@dataclass(frozen=True)
class SmoothJob:
    pose3d: Path
    out: Path
    lamb: float
    params: dict
    inputs: dict
    fingerprint: str


def smooth_clip(clip, lamb: float):
    """A motion clip HP-filtered: joints, root path, feet and hands (contact probabilities, sight
    rays and the hands' presence, observations rather than motion, pass unchanged)."""
    trend = hp_trend(clip.joints.reshape(len(clip.joints), -1), lamb).reshape(clip.joints.shape)
    root = None if clip.root is None else hp_trend(clip.root.astype(np.float64), lamb).astype(np.float32)
    feet = None if clip.feet is None else hp_trend(clip.feet.reshape(len(clip.feet), -1).astype(np.float64),
                                                  lamb).reshape(clip.feet.shape).astype(np.float32)
    hands = None if clip.hands is None else hp_trend(clip.hands.reshape(len(clip.hands), -1).astype(np.float64),
                                                    lamb).reshape(clip.hands.shape).astype(np.float32)
    return replace(clip, joints=trend.astype(np.float32), root=root, feet=feet, hands=hands)


def smooth_segment(job: SmoothJob) -> dict:
    """HP-filter every clip of a segment; per-clip QC (acceleration, limb-length CV) goes in the metadata."""
    from pipeline.motion.motionfile import read_motion, write_motion
    from pipeline.motion.quality import limb_length_cv, mean_acceleration

    motion = read_motion(job.pose3d)
    clips, qc = [], {}
    for clip in motion.clips:
        smoothed = smooth_clip(clip, job.lamb)
        clips.append(smoothed)
        qc[clip.clip_id] = {
            "frames": int(len(clip.frame)),
            "mean_acc_before": round(mean_acceleration(clip.joints, motion.fps), 3),
            "mean_acc_after": round(mean_acceleration(smoothed.joints, motion.fps), 3),
            "limb_cv": round(limb_length_cv(smoothed.joints), 4),
            "interpolated_share": round(float(clip.interpolated.mean()), 4),
        }
    segment = {"clip_qc": qc, **{k: motion.meta.get(k) for k in ("segment_id", "fps", "width", "height")}}
    write_motion(job.out, clips, segment, fingerprint=job.fingerprint, params=job.params, inputs=job.inputs)
    return qc
