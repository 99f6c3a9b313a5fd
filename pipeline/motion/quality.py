"""Quality measures of 3D motion clips, for metrics and for spotting bad clips."""

from __future__ import annotations

import numpy as np

from pipeline.motion.lifting.geometry import p_mpjpe_per_frame
from pipeline.motion.mocap.skeleton import H36M_BONES

LIMBS = [H36M_BONES.index(b) for b in ((1, 2), (2, 3), (4, 5), (5, 6), (11, 12), (12, 13), (14, 15), (15, 16))]


def mean_acceleration(joints: np.ndarray, fps: float) -> float:
    """Mean joint acceleration magnitude (m/s^2): jitter shows up here first."""
    if len(joints) < 3:
        return 0.0
    acc = np.diff(joints, n=2, axis=0) * fps * fps
    return float(np.linalg.norm(acc, axis=-1).mean())


def limb_length_cv(joints: np.ndarray) -> float:
    """Mean coefficient of variation of the limb bones over the clip (0 for a rigid skeleton)."""
    lengths = np.stack([np.linalg.norm(joints[:, H36M_BONES[i][1]] - joints[:, H36M_BONES[i][0]], axis=-1)
                        for i in LIMBS], -1)
    return float((lengths.std(0) / np.maximum(lengths.mean(0), 1e-9)).mean())


def limb_lengths(joints: np.ndarray) -> np.ndarray:
    """Median length of each limb bone (thigh, shin, upper arm, forearm; right and left)."""
    return np.array([np.median(np.linalg.norm(joints[:, H36M_BONES[i][1]] - joints[:, H36M_BONES[i][0]], axis=-1))
                     for i in LIMBS])


def sync_ratio(a: np.ndarray, b: np.ndarray, fps: float,
               shifts_s: tuple[float, ...] = (1.0, 1.5, 2.0, 2.5, 3.0)) -> dict:
    """Two dancers performing the same choreography in sync (T x J x 3 each, on one clock): how
    much closer their poses are at the same instant than with one of them shifted by 1-3 s, after
    rotation and scale alignment. A 3D consistency measure on real video without ground truth: the
    ratio (same instant / shifted) falls as the lifter and the grounding get better."""
    n = min(len(a), len(b))
    same = float(p_mpjpe_per_frame(b[:n], a[:n]).mean())
    shifted = []
    for shift in shifts_s:
        k = int(round(shift * fps))
        if k < n:  # both ways: b behind a, and a behind b
            shifted.append(p_mpjpe_per_frame(b[k:n], a[: n - k]).mean())
            shifted.append(p_mpjpe_per_frame(b[: n - k], a[k:n]).mean())
    other = float(np.mean(shifted)) if shifted else float("nan")
    return {"same_instant_m": same, "shifted_m": other, "ratio": same / other if other else float("nan")}
