"""The root's path in camera space, from the lifted pose and the 2D keypoints it came from.

The lifter gives a root-relative pose in the camera's orientation; where the body is follows
from where that pose projects. With a focal length assumed from the frame size (a phone's
26 mm-equivalent main camera), the root translation T of each frame solves a small linear
least-squares problem over the twelve body keypoints that COCO and Human3.6M share: for a
joint at X + T seen at pixel (u, v) from the principal point, f (X + T)_x = u (X + T)_z and
f (X + T)_y = v (X + T)_z. A wrong focal length or body size scales the whole path (depth
and travel together), which is why errors are also reported after one scale and offset per
clip.
"""

from __future__ import annotations

import numpy as np

from pipeline.motion.mocap.skeleton import COCO_H36M_SHARED


def assumed_focal(width: float, height: float, equiv_mm: float = 26.0) -> float:
    """Focal length in pixels of a lens of ``equiv_mm`` 35 mm-equivalent (diagonal 43.27 mm)."""
    return equiv_mm / 43.27 * float(np.hypot(width, height))


def root_from_2d(joints: np.ndarray, keypoints: np.ndarray, focal: float, width: float, height: float,
                 scores: np.ndarray | None = None) -> np.ndarray:
    """Per-frame root translation (T x 3, metres, camera frame) placing the root-relative pose
    ``joints`` (T x 17 x 3, H36M) where its COCO ``keypoints`` (T x 17 x 2, pixels) are seen."""
    coco, h36m = (np.array(i) for i in zip(*COCO_H36M_SHARED))
    xyz = joints[:, h36m].astype(np.float64)
    uv = keypoints[:, coco, :2].astype(np.float64) - np.array([width / 2, height / 2])
    w = np.ones(uv.shape[:2]) if scores is None else np.clip(scores[:, coco], 1e-3, None)
    # Rows f*Tx - u*Tz = u*Z - f*X and f*Ty - v*Tz = v*Z - f*Y, weighted, solved per frame.
    frames, n = uv.shape[:2]
    a = np.zeros((frames, 2 * n, 3))
    b = np.zeros((frames, 2 * n))
    for axis in (0, 1):
        rows = slice(axis * n, (axis + 1) * n)
        a[:, rows, axis] = focal
        a[:, rows, 2] = -uv[..., axis]
        b[:, rows] = uv[..., axis] * xyz[..., 2] - focal * xyz[..., axis]
    sw = np.sqrt(np.concatenate([w, w], 1))
    a, b = a * sw[..., None], b * sw
    ata = np.einsum("tki,tkj->tij", a, a)
    atb = np.einsum("tki,tk->ti", a, b)
    return np.linalg.solve(ata, atb[..., None])[..., 0]


def align_scale_offset(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """``pred`` (T x 3) after the one scale and offset that bring it nearest ``true`` (least squares)."""
    p, t = pred - pred.mean(0), true - true.mean(0)
    scale = float((p * t).sum() / max((p * p).sum(), 1e-12))
    return scale * p + true.mean(0)
