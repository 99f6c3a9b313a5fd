"""Top-down 2D pose on person crops: MoveNet (single-person, batch 1) and RTMPose (SimCC, batched).

Both return COCO-17 keypoints as (x, y, score) in image pixels.
"""

from __future__ import annotations

import cv2
import numpy as np

COCO17 = (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle",
)
RGB_MEAN = np.array([123.675, 116.28, 103.53], np.float32)
RGB_STD = np.array([58.395, 57.12, 57.375], np.float32)


def crop_transform(box: np.ndarray, out_w: int, out_h: int, padding: float = 1.25) -> np.ndarray:
    """2x3 affine taking the padded, aspect-corrected box to an ``out_w`` x ``out_h`` crop.

    The crop keeps the picture undistorted: the box is widened or heightened to the crop's
    aspect ratio, then scaled by ``padding`` around its centre.
    """
    x1, y1, x2, y2 = (float(v) for v in box)
    cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
    w, h = max(x2 - x1, 1.0), max(y2 - y1, 1.0)
    aspect = out_w / out_h
    if w > h * aspect:
        h = w / aspect
    else:
        w = h * aspect
    s = out_w / (w * padding)
    return np.array([[s, 0.0, out_w / 2 - s * cx], [0.0, s, out_h / 2 - s * cy]], np.float64)


def to_image(points: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """Map crop-pixel points (..., 2) back to the image through the inverse of ``matrix``."""
    s, tx, ty = matrix[0, 0], matrix[0, 2], matrix[1, 2]
    return np.stack([(points[..., 0] - tx) / s, (points[..., 1] - ty) / s], axis=-1)


def warp(image: np.ndarray, matrix: np.ndarray, out_w: int, out_h: int) -> np.ndarray:
    return cv2.warpAffine(image, matrix, (out_w, out_h), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0))


class MoveNetPose:
    """MoveNet SinglePose (uint8 NHWC RGB 192x192 in; y, x, score in [0, 1] out); one crop per call."""

    def __init__(self, session, input_size: tuple[int, int] = (192, 192), padding: float = 1.25):
        self.session = session
        self.size = input_size
        self.padding = padding
        self.input_name = session.get_inputs()[0].name

    def estimate(self, image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        out = np.zeros((len(boxes), 17, 3), np.float32)
        w, h = self.size
        for i, box in enumerate(boxes):
            m = crop_transform(box, w, h, self.padding)
            crop = cv2.cvtColor(warp(image, m, w, h), cv2.COLOR_BGR2RGB)
            (raw,) = self.session.run(None, {self.input_name: crop[None]})
            yx_score = raw.reshape(17, 3)
            crop_xy = np.stack([yx_score[:, 1] * w, yx_score[:, 0] * h], axis=-1)
            out[i, :, :2] = to_image(crop_xy, m)
            out[i, :, 2] = yx_score[:, 2]
        return out


def decode_simcc(simcc_x: np.ndarray, simcc_y: np.ndarray, split_ratio: float = 2.0) -> np.ndarray:
    """SimCC vectors (N, K, Wr) and (N, K, Hr) -> (N, K, 3): crop x, y and score.

    The score is the smaller of the two maxima, as MMPose's ``get_simcc_maximum`` does.
    """
    x = simcc_x.argmax(-1) / split_ratio
    y = simcc_y.argmax(-1) / split_ratio
    score = np.minimum(simcc_x.max(-1), simcc_y.max(-1))
    return np.stack([x, y, score], axis=-1).astype(np.float32)


class RTMPose:
    """RTMPose SimCC exports (float NCHW RGB normalised, 256x192 by default); all crops in one call."""

    def __init__(self, session, input_size: tuple[int, int] = (192, 256), padding: float = 1.25,
                 split_ratio: float = 2.0):
        self.session = session
        self.size = input_size
        self.padding = padding
        self.split_ratio = split_ratio
        self.input_name = session.get_inputs()[0].name
        w, h = input_size
        lengths = {o.name: o.shape[-1] for o in session.get_outputs()}
        by_length = {v: k for k, v in lengths.items()}
        self.x_name = by_length.get(int(w * split_ratio), session.get_outputs()[0].name)
        self.y_name = by_length.get(int(h * split_ratio), session.get_outputs()[1].name)

    def estimate(self, image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        if len(boxes) == 0:
            return np.zeros((0, 17, 3), np.float32)
        w, h = self.size
        matrices = [crop_transform(box, w, h, self.padding) for box in boxes]
        crops = np.stack([cv2.cvtColor(warp(image, m, w, h), cv2.COLOR_BGR2RGB) for m in matrices])
        batch = ((crops.astype(np.float32) - RGB_MEAN) / RGB_STD).transpose(0, 3, 1, 2)
        simcc_x, simcc_y = self.session.run([self.x_name, self.y_name], {self.input_name: np.ascontiguousarray(batch)})
        decoded = decode_simcc(simcc_x, simcc_y, self.split_ratio)
        out = decoded.copy()
        for i, m in enumerate(matrices):
            out[i, :, :2] = to_image(decoded[i, :, :2], m)
        return out


def decode_heatmaps(heatmaps: np.ndarray, stride: float) -> np.ndarray:
    """(N, K, H, W) heatmaps -> (N, K, 3) crop-pixel x, y and peak value.

    The peak is moved a quarter of a heatmap pixel toward its larger neighbour (the classic
    sub-pixel refinement of SimpleBaseline / PaddleDetection), then mapped to the centre of
    its ``stride``-pixel cell in the crop.
    """
    n, k, h, w = heatmaps.shape
    flat = heatmaps.reshape(n, k, -1)
    idx = flat.argmax(-1)
    score = np.take_along_axis(flat, idx[..., None], -1)[..., 0]
    x, y = (idx % w).astype(np.float64), (idx // w).astype(np.float64)
    xi, yi = x.astype(int), y.astype(int)
    b, j = np.meshgrid(np.arange(n), np.arange(k), indexing="ij")
    right = heatmaps[b, j, yi, np.clip(xi + 1, 0, w - 1)]
    left = heatmaps[b, j, yi, np.clip(xi - 1, 0, w - 1)]
    down = heatmaps[b, j, np.clip(yi + 1, 0, h - 1), xi]
    up = heatmaps[b, j, np.clip(yi - 1, 0, h - 1), xi]
    inside_x, inside_y = (xi > 0) & (xi < w - 1), (yi > 0) & (yi < h - 1)
    x += np.where(inside_x, 0.25 * np.sign(right - left), 0.0)
    y += np.where(inside_y, 0.25 * np.sign(down - up), 0.0)
    return np.stack([x * stride + (stride - 1) / 2, y * stride + (stride - 1) / 2, score], -1).astype(np.float32)


IMAGENET_MEAN = np.array([0.485, 0.456, 0.406], np.float32)
IMAGENET_STD = np.array([0.229, 0.224, 0.225], np.float32)


class TinyPose:
    """PP-TinyPose heatmap exports (NCHW RGB, ImageNet-normalised, 256x192, batch 1): one crop per call."""

    def __init__(self, session, input_size: tuple[int, int] = (192, 256), padding: float = 1.25):
        self.session = session
        self.size = input_size
        self.padding = padding
        self.input_name = session.get_inputs()[0].name
        self.heatmap_name = next(o.name for o in session.get_outputs() if len(o.shape) == 4)

    def estimate(self, image: np.ndarray, boxes: np.ndarray) -> np.ndarray:
        out = np.zeros((len(boxes), 17, 3), np.float32)
        w, h = self.size
        for i, box in enumerate(boxes):
            m = crop_transform(box, w, h, self.padding)
            crop = cv2.cvtColor(warp(image, m, w, h), cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
            tensor = ((crop - IMAGENET_MEAN) / IMAGENET_STD).transpose(2, 0, 1)[None]
            (heatmaps,) = self.session.run([self.heatmap_name], {self.input_name: np.ascontiguousarray(tensor)})
            decoded = decode_heatmaps(heatmaps, stride=w / heatmaps.shape[-1])[0]
            out[i, :, :2] = to_image(decoded[:, :2], m)
            out[i, :, 2] = decoded[:, 2]
        return out
