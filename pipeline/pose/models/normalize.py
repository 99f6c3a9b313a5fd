"""Model inputs from uint8 pictures by a per-channel lookup table: ``(v / divide - mean) / std`` for
each of the 256 values of each channel, computed once in float32, so a frame's input costs one
OpenCV ``LUT`` pass instead of three float passes over it (the same float32 values, bit for bit)."""

from __future__ import annotations

import cv2
import numpy as np


def channel_table(mean: np.ndarray, std: np.ndarray, divide: float = 1.0, swap_rb: bool = False) -> np.ndarray:
    """The (256 x 1 x 3) float32 table for pictures in BGR order; ``mean`` and ``std`` are in the
    model's channel order, RGB when ``swap_rb``."""
    values = np.arange(256, dtype=np.float32)[:, None] / np.float32(divide)
    mean, std = np.asarray(mean, np.float32), np.asarray(std, np.float32)
    if swap_rb:
        mean, std = mean[::-1], std[::-1]
    return ((values - mean[None, :]) / std[None, :]).astype(np.float32).reshape(256, 1, 3)


def to_tensor(pictures: np.ndarray, table: np.ndarray, swap_rb: bool = False) -> np.ndarray:
    """(N x H x W x 3) or (H x W x 3) uint8 BGR pictures -> contiguous float32 (N x 3 x H x W) through
    ``table`` (:func:`channel_table`), channels reversed to RGB when ``swap_rb``."""
    pictures = np.asarray(pictures, np.uint8)
    batch = pictures[None] if pictures.ndim == 3 else pictures
    out = np.stack([cv2.LUT(p, table) for p in batch]).transpose(0, 3, 1, 2)
    return np.ascontiguousarray(out[:, ::-1] if swap_rb else out)
