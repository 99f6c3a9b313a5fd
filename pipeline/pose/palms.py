"""MediaPipe's palm detector (full), the first half of MediaPipe's own hand pipeline: `eval hands
--regions palm` runs it as the peer the body's regions are measured against.

The whole image is padded to a square and scaled to 192 x 192 (RGB in [0, 1]); per anchor of
MediaPipe's SSD grid (24 x 24 cells of 2 anchors at stride 8, 12 x 12 of 6 at stride 16: 2016) the
model gives a box and seven palm points as offsets in input pixels, and a logit. Boxes at
``min_score`` or above are kept after non-maximum suppression at ``overlap``. The hand's region
is MediaPipe's: the palm box turned so the wrist -> middle finger's knuckle (points 0 and 2) points
up, moved half its height towards the fingers, a square 2.6 times its longer side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.pose.models.pose import roi_transform

INPUT = 192
GRIDS = ((24, 2), (12, 6))  # (cells per side, anchors per cell)
REGION_SCALE, REGION_SHIFT = 2.6, 0.5


def anchor_centres() -> np.ndarray:
    """2016 x 2 anchor centres in [0, 1], in the model's order (cell by cell, row by row)."""
    return np.array([((x + 0.5) / g, (y + 0.5) / g) for g, per in GRIDS for y in range(g) for x in range(g)
                     for _ in range(per)])


@dataclass(frozen=True)
class Palm:
    box: np.ndarray     # x1, y1, x2, y2 in image pixels
    points: np.ndarray  # 7 x 2 palm points in image pixels (0: wrist, 2: middle finger's knuckle)
    score: float


class PalmDetector:
    def __init__(self, session, min_score: float = 0.5, overlap: float = 0.3) -> None:
        self.session, self.min_score, self.overlap = session, min_score, overlap
        self.input_name = session.get_inputs()[0].name
        self.anchors = anchor_centres()

    def detect(self, image: np.ndarray) -> list[Palm]:
        import cv2

        height, width = image.shape[:2]
        side = max(height, width)
        square = np.zeros((side, side, 3), np.uint8)
        square[:height, :width] = image
        tensor = cv2.resize(square, (INPUT, INPUT), interpolation=cv2.INTER_AREA)[..., ::-1].astype(np.float32) / 255
        raw, logits = self.session.run(None, {self.input_name: tensor[None]})
        raw, logits = raw[0].astype(np.float64), logits[0, :, 0].astype(np.float64)
        scores = 1.0 / (1.0 + np.exp(-np.clip(logits, -100, 100)))
        keep = np.flatnonzero(scores >= self.min_score)
        if not len(keep):
            return []
        centre = raw[keep, :2] / INPUT + self.anchors[keep]
        size = raw[keep, 2:4] / INPUT
        points = raw[keep, 4:18].reshape(-1, 7, 2) / INPUT + self.anchors[keep, None, :]
        boxes = np.hstack([centre - size / 2, centre + size / 2]) * side
        chosen = cv2.dnn.NMSBoxes([[float(x1), float(y1), float(x2 - x1), float(y2 - y1)] for x1, y1, x2, y2 in boxes],
                                  scores[keep].tolist(), self.min_score, self.overlap)
        return [Palm(boxes[i], points[i] * side, float(scores[keep][i])) for i in np.ravel(chosen)]


def region_from_palm(palm: Palm, size: int = 224) -> np.ndarray:
    """MediaPipe's hand region from a palm (see the module's docstring)."""
    up = palm.points[2] - palm.points[0]
    up = up / max(float(np.hypot(*up)), 1e-6)
    (x1, y1, x2, y2) = palm.box
    centre = np.array([(x1 + x2) / 2, (y1 + y2) / 2]) + REGION_SHIFT * (y2 - y1) * up
    half = REGION_SCALE * max(x2 - x1, y2 - y1) / 2
    return roi_transform(centre, centre + up * half, size, 1.0)
