"""Cameras, normalisation and error measures shared by training and inference (numpy only)."""

from __future__ import annotations

import numpy as np


def normalise_screen(xy: np.ndarray, width: float, height: float) -> np.ndarray:
    """VideoPose3D's normalisation: x in [0, w] -> [-1, 1], aspect ratio kept (X*2/w - (1, h/w))."""
    return xy / width * 2 - np.array([1.0, height / width])


def normalise_centred(xy: np.ndarray, window: int) -> np.ndarray:
    """Keypoints (T x 17 x 2, COCO, or 21 with the feet) about the hips' midpoint, divided by the body's size in the
    image: the root-mean-square distance of the keypoints from their centre, median-filtered
    over ``window`` frames (the receptive field), so the scale follows a dancer who comes nearer
    but not a pose that opens its arms. Camera, framing and person size no longer reach the model."""
    centre = (xy[:, 11] + xy[:, 12]) / 2
    return (xy - centre[:, None]) / np.maximum(body_size(xy, window), 1e-6)[:, None, None]


def body_size(xy: np.ndarray, window: int) -> np.ndarray:
    """Per frame, the root-mean-square distance of the 17 body keypoints (with or without the feet
    after them) from their centre, median-filtered over ``window`` frames."""
    from scipy.ndimage import median_filter

    body = xy[:, :17]
    spread = np.sqrt(((body - body.mean(1, keepdims=True)) ** 2).sum(-1).mean(-1))
    return median_filter(spread, size=max(1, min(window, len(spread))), mode="nearest")


def normalise(xy: np.ndarray, width: float, height: float, method: str, window: int) -> np.ndarray:
    """The lifter's input normalisation: ``screen`` (VideoPose3D's, the official weights') or ``centred``."""
    if method == "screen":
        return normalise_screen(xy, width, height)
    if method == "centred":
        return normalise_centred(xy, window)
    raise ValueError(f"unknown input normalisation {method!r} (screen or centred)")


def look_at(position: np.ndarray, target: np.ndarray) -> np.ndarray:
    """World-to-camera rotation (rows: camera x right, y down, z forward), world y up."""
    forward = target - position
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right = right / np.linalg.norm(right)
    down = np.cross(forward, right)
    return np.stack([right, down, forward])


def to_camera(points: np.ndarray, rotation: np.ndarray, position: np.ndarray) -> np.ndarray:
    return (points - position) @ rotation.T


def project(points_cam: np.ndarray, focal: float, width: float, height: float) -> np.ndarray:
    """Pinhole projection to pixels (principal point at the image centre)."""
    z = np.maximum(points_cam[..., 2:3], 1e-3)
    return points_cam[..., :2] / z * focal + np.array([width / 2, height / 2])


def mpjpe(pred: np.ndarray, target: np.ndarray) -> float:
    """Mean per-joint position error (same units as the inputs)."""
    return float(np.linalg.norm(pred - target, axis=-1).mean())


def n_mpjpe(pred: np.ndarray, target: np.ndarray) -> float:
    """MPJPE after the per-frame scale that brings pred nearest target (least squares; the
    N-MPJPE of Rhodin et al. 2018 and VideoPose3D): what is left once the size is forgiven."""
    p = pred.reshape(-1, *pred.shape[-2:])
    t = target.reshape(-1, *target.shape[-2:])
    scale = (p * t).sum((1, 2)) / np.maximum((p * p).sum((1, 2)), 1e-12)
    return mpjpe(p * scale[:, None, None], t)


def p_mpjpe(pred: np.ndarray, target: np.ndarray) -> float:
    """MPJPE after a per-frame similarity (Procrustes) alignment of pred to target."""
    return float(p_mpjpe_per_frame(pred, target).mean())


def p_mpjpe_per_frame(pred: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Per frame (... x J x 3 -> frames), the mean joint distance after the rotation, scale and
    offset that bring that frame of pred nearest target (Procrustes)."""
    p = pred.reshape(-1, *pred.shape[-2:])
    t = target.reshape(-1, *target.shape[-2:])
    mu_p, mu_t = p.mean(1, keepdims=True), t.mean(1, keepdims=True)
    p0, t0 = p - mu_p, t - mu_t
    norm_p = np.maximum(np.sqrt((p0 ** 2).sum((1, 2), keepdims=True)), 1e-12)  # a collapsed pose stays finite
    norm_t = np.maximum(np.sqrt((t0 ** 2).sum((1, 2), keepdims=True)), 1e-12)
    p0, t0 = p0 / norm_p, t0 / norm_t
    u, s, vt = np.linalg.svd(np.einsum("fji,fjk->fik", t0, p0))
    v = vt.transpose(0, 2, 1)
    r = v @ u.transpose(0, 2, 1)
    # no reflections
    det = np.sign(np.linalg.det(r))
    v[:, :, -1] *= det[:, None]
    s[:, -1] *= det
    r = v @ u.transpose(0, 2, 1)
    scale = s.sum(1)[:, None, None] * norm_t / norm_p
    aligned = scale * ((p - mu_p) @ r) + mu_t
    return np.linalg.norm(aligned - t, axis=-1).mean(1)
