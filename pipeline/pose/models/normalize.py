"""Model inputs from uint8 pictures by a per-channel lookup table: ``(v / divide - mean) / std`` for
each of the 256 values of each channel, computed once in float32, so a frame's input costs one
OpenCV ``LUT`` pass instead of three float passes over it (the same float32 values, bit for bit)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

IMAGENET_MEAN_RGB = np.array([0.485, 0.456, 0.406], np.float32)  # of pictures scaled to [0, 1]
IMAGENET_STD_RGB = np.array([0.229, 0.224, 0.225], np.float32)


@dataclass(frozen=True)
class InputTable:
    """How a model wants its input: ``(v / divide - mean) / std`` per channel, in ``mean``'s and
    ``std``'s channel order (RGB when ``rgb``, else BGR); pictures come in BGR."""

    mean: tuple[float, ...]
    std: tuple[float, ...]
    divide: float = 1.0
    rgb: bool = False
    table: np.ndarray = field(init=False, repr=False, compare=False)  # 256 x 1 x 3, the pictures' BGR order

    def __post_init__(self) -> None:
        values = np.arange(256, dtype=np.float32)[:, None] / np.float32(self.divide)
        mean, std = np.asarray(self.mean, np.float32), np.asarray(self.std, np.float32)
        if self.rgb:
            mean, std = mean[::-1], std[::-1]
        table = ((values - mean[None, :]) / std[None, :]).astype(np.float32).reshape(256, 1, 3)
        object.__setattr__(self, "table", table)

    def __call__(self, pictures: np.ndarray) -> np.ndarray:
        """(N x H x W x 3) or (H x W x 3) uint8 BGR pictures -> contiguous float32 (N x 3 x H x W)."""
        import cv2  # imported where used: the mocap skeleton reaches this package in stages that need no OpenCV

        pictures = np.asarray(pictures, np.uint8)
        batch = pictures[None] if pictures.ndim == 3 else pictures
        out = np.stack([cv2.LUT(p, self.table) for p in batch]).transpose(0, 3, 1, 2)
        return np.ascontiguousarray(out[:, ::-1] if self.rgb else out)


IMAGENET = InputTable(tuple(IMAGENET_MEAN_RGB), tuple(IMAGENET_STD_RGB), divide=255.0, rgb=True)
