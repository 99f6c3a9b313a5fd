"""Quality measures of 3D motion clips, for metrics and for spotting bad clips."""

from __future__ import annotations

import numpy as np

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


def aligned_pose_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per frame, the mean joint distance (m) between poses ``a`` and ``b`` (T x J x 3) after the
    rotation and scale that bring each frame of ``b`` nearest ``a`` (about their centres; Umeyama)."""
    x = b - b.mean(1, keepdims=True)
    y = a - a.mean(1, keepdims=True)
    u, d, vt = np.linalg.svd(np.einsum("tji,tjk->tik", y, x))
    sign = np.ones_like(d)
    sign[:, 2] = np.sign(np.linalg.det(u @ vt))
    rotation = u @ (sign[:, :, None] * vt)
    scale = (d * sign).sum(1) / np.maximum((x ** 2).sum((1, 2)), 1e-12)
    aligned = scale[:, None, None] * np.einsum("tij,tkj->tki", rotation, x)
    return np.linalg.norm(aligned - y, axis=-1).mean(1)


def sync_ratio(a: np.ndarray, b: np.ndarray, fps: float,
               shifts_s: tuple[float, ...] = (1.0, 1.5, 2.0, 2.5, 3.0)) -> dict:
    """Two dancers performing the same choreography in sync (T x J x 3 each, on one clock): how
    much closer their poses are at the same instant than with one of them shifted by 1-3 s, after
    rotation and scale alignment. A 3D consistency measure on real video without ground truth: the
    ratio (same instant / shifted) falls as the lifter and the grounding get better."""
    n = min(len(a), len(b))
    same = float(aligned_pose_distance(a[:n], b[:n]).mean())
    shifted = []
    for shift in shifts_s:
        k = int(round(shift * fps))
        if k < n:  # both ways: b behind a, and a behind b
            shifted.append(aligned_pose_distance(a[: n - k], b[k:n]).mean())
            shifted.append(aligned_pose_distance(a[k:n], b[: n - k]).mean())
    other = float(np.mean(shifted)) if shifted else float("nan")
    return {"same_instant_m": same, "shifted_m": other, "ratio": same / other if other else float("nan")}
