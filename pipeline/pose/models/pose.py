"""Top-down 2D pose on person crops: MoveNet, RTMPose (SimCC), PP-TinyPose (heatmaps), BlazePose.

Every wrapper's ``estimate(image, boxes)`` returns a :class:`PoseBatch`: COCO-17 keypoints as
(x, y, score) in image pixels, plus heels and toes and metric world landmarks where the
model gives them (BlazePose).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.pose.models.batching import run_batched
from pipeline.pose.models.normalize import IMAGENET
from pipeline.pose.pose2dfile import FEET

RGB_MEAN = np.array([123.675, 116.28, 103.53], np.float32)
RGB_STD = np.array([58.395, 57.12, 57.375], np.float32)


@dataclass(frozen=True)
class PoseBatch:
    """The poses of N people in one image."""

    keypoints: np.ndarray           # N x 17 x 3: COCO-17 (x, y, score), image pixels
    feet: np.ndarray                # N x 4 x 3: FOOT_POINTS (x, y, score); 0 scores where the model has no feet
    world: np.ndarray | None = None  # N x 33 x 3: BlazePose world landmarks (m, origin between the hips)

    def __len__(self) -> int:
        return len(self.keypoints)

    @staticmethod
    def body_only(keypoints: np.ndarray) -> "PoseBatch":
        keypoints = np.asarray(keypoints, np.float32).reshape(-1, 17, 3)
        return PoseBatch(keypoints, np.zeros((len(keypoints), FEET, 3), np.float32))


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
    """Map crop-pixel points (..., 2) back to the image through the inverse of the 2x3 ``matrix``."""
    import cv2  # imported where used, as in warp: reading the models' tables needs no OpenCV

    inverse = cv2.invertAffineTransform(np.asarray(matrix, np.float64))
    return points @ inverse[:, :2].T + inverse[:, 2]


def warp(image: np.ndarray, matrix: np.ndarray, out_w: int, out_h: int) -> np.ndarray:
    import cv2

    return cv2.warpAffine(image, matrix, (out_w, out_h), flags=cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0))


def rgb_crop(image: np.ndarray, matrix: np.ndarray, out_w: int, out_h: int) -> np.ndarray:
    """The crop ``matrix`` takes from a BGR ``image``, in RGB."""
    import cv2

    return cv2.cvtColor(warp(image, matrix, out_w, out_h), cv2.COLOR_BGR2RGB)


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
            crop = rgb_crop(image, m, w, h)
            (raw,) = self.session.run(None, {self.input_name: crop[None]})
            yx_score = raw.reshape(17, 3)
            crop_xy = np.stack([yx_score[:, 1] * w, yx_score[:, 0] * h], axis=-1)
            out[i, :, :2] = to_image(crop_xy, m)
            out[i, :, 2] = yx_score[:, 2]
        return PoseBatch.body_only(out)


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
            return PoseBatch.body_only(np.zeros((0, 17, 3), np.float32))
        w, h = self.size
        matrices = [crop_transform(box, w, h, self.padding) for box in boxes]
        crops = np.stack([rgb_crop(image, m, w, h) for m in matrices])
        batch = ((crops.astype(np.float32) - RGB_MEAN) / RGB_STD).transpose(0, 3, 1, 2)
        simcc_x, simcc_y = self.session.run([self.x_name, self.y_name], {self.input_name: np.ascontiguousarray(batch)})
        decoded = decode_simcc(simcc_x, simcc_y, self.split_ratio)
        out = decoded.copy()
        for i, m in enumerate(matrices):
            out[i, :, :2] = to_image(decoded[i, :, :2], m)
        return PoseBatch.body_only(out)


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




class TinyPose:
    """PP-TinyPose heatmap exports (NCHW RGB, ImageNet-normalised, 256x192): a frame's crops in one
    call when the session takes a batch (``batching.any_batch``), one by one otherwise."""

    def __init__(self, session, input_size: tuple[int, int] = (192, 256), padding: float = 1.25):
        self.session = session
        self.size = input_size
        self.padding = padding
        self.input_name = session.get_inputs()[0].name
        self.heatmap_name = next(o.name for o in session.get_outputs() if len(o.shape) == 4)

    def estimate(self, image: np.ndarray, boxes: np.ndarray) -> PoseBatch:
        out = np.zeros((len(boxes), 17, 3), np.float32)
        if not len(boxes):
            return PoseBatch.body_only(out)
        w, h = self.size
        matrices = [crop_transform(box, w, h, self.padding) for box in boxes]
        tensors = IMAGENET(np.stack([warp(image, m, w, h) for m in matrices]))
        heatmaps = run_batched(self.session, self.heatmap_name, self.input_name, tensors)
        decoded = decode_heatmaps(heatmaps, stride=w / heatmaps.shape[-1])
        for i, m in enumerate(matrices):
            out[i, :, :2] = to_image(decoded[i, :, :2], m)
            out[i, :, 2] = decoded[i, :, 2]
        return PoseBatch.body_only(out)


# BlazePose GHUM (MODELS.md 4b): 33 body landmarks, then auxiliary ROI points (33: hip centre,
# 34: a point above the head whose distance from the hips sets the ROI's size).
BLAZE_TO_COCO17 = (0, 2, 5, 7, 8, 11, 12, 13, 14, 15, 16, 23, 24, 25, 26, 27, 28)
BLAZE_FEET = (29, 30, 31, 32)  # left heel, right heel, left foot index (toe tip), right foot index


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(x, -60, 60)))


def roi_transform(center: np.ndarray, scale_point: np.ndarray, size: int, scale: float = 1.25) -> np.ndarray:
    """2x3 affine onto a ``size`` square crop, MediaPipe's pose ROI from two points.

    The crop is centred on ``center`` (the hips), its side is ``scale`` x twice the distance to
    ``scale_point``, and it is rotated so that the direction centre -> scale point is up:
    a dancer upside down or lying comes out upright.
    """
    v = np.asarray(scale_point, np.float64) - np.asarray(center, np.float64)
    side = max(2.0 * float(np.hypot(*v)) * scale, 1.0)
    phi = -np.pi / 2 - np.arctan2(v[1], v[0])  # rotation taking v to (0, -|v|), y pointing down
    k = size / side
    rot = k * np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    shift = size / 2 - rot @ np.asarray(center, np.float64)
    return np.hstack([rot, shift[:, None]])


class BlazePose:
    """BlazePose GHUM Full (NHWC RGB [0, 1] 256x256, batch 1), with MediaPipe's region of interest.

    A person box gives a first square crop, upright; if the model's heatmaps are weak there
    (mean peak logit under ``orientation_check``: the body is probably upside down or lying),
    the crop is also tried turned by 90, 180 and 270 degrees and the strongest kept. The
    landmarks of that pass place the hips' ROI point and the scale point, and a second pass on
    that rotated, torso-scaled crop (MediaPipe's ROI) gives the landmarks kept. (MediaPipe
    takes the first ROI from its own detector, whose TFLite does not convert, and in video
    from the previous frame; a fresh first pass per frame costs one more crop but cannot
    drift.) Scores are the sigmoid of the visibility logits times the pose presence.
    """

    def __init__(self, session, input_size: tuple[int, int] = (256, 256), padding: float = 1.25, passes: int = 2,
                 orientation_check: float = 0.5):
        self.session = session
        self.size = input_size[0]
        self.padding = padding
        self.passes = passes
        self.orientation_check = orientation_check
        self.input_name = session.get_inputs()[0].name
        shapes = {o.name: o.shape for o in session.get_outputs()}
        self.landmarks_name = next(n for n, s in shapes.items() if s[-1] == 195)
        self.presence_name = next(n for n, s in shapes.items() if len(s) == 2 and s[-1] == 1)
        self.world_name = next(n for n, s in shapes.items() if s[-1] == 117)
        self.heatmap_name = next(n for n, s in shapes.items() if len(s) == 4 and s[-1] == 39)

    @staticmethod
    def unused_output(name: str, shape: tuple) -> bool:
        """The segmentation mask (N x 256 x 256 x 1), which nothing here reads: a session built
        without it (``create_session(unused_outputs=...)``) runs in half the time."""
        return len(shape) == 4 and shape[-1] == 1

    def _run(self, image: np.ndarray, matrices: list[np.ndarray]) -> list[tuple[np.ndarray, float, np.ndarray, float]]:
        """One call on the crops ``matrices`` give: per crop, landmarks, presence, world, strength."""
        if not matrices:
            return []
        crops = np.stack([rgb_crop(image, m, self.size, self.size) for m in matrices])
        landmarks, presence, world, heatmaps = run_batched(
            self.session, [self.landmarks_name, self.presence_name, self.world_name, self.heatmap_name],
            self.input_name, crops.astype(np.float32) / 255.0)
        strength = heatmaps[..., :33].reshape(len(crops), -1, 33).max(1).mean(1)
        return [(landmarks[i].reshape(39, 5), float(presence[i].ravel()[0]), world[i].reshape(39, 3),
                 float(strength[i])) for i in range(len(crops))]

    def _first_crop(self, box: np.ndarray) -> list[np.ndarray]:
        """The box's square crop upright, then turned a quarter, a half and three quarters."""
        centre = (np.asarray(box[:2], np.float64) + np.asarray(box[2:], np.float64)) / 2
        side = self.padding * max(float(box[2] - box[0]), float(box[3] - box[1]), 1.0)
        out = []
        for angle in (0.0, 0.5 * np.pi, np.pi, 1.5 * np.pi):  # where the head is assumed to point
            head = centre + side / 2.5 * np.array([np.sin(angle), -np.cos(angle)])
            out.append(roi_transform(centre, head, self.size, scale=1.25))
        return out

    def estimate(self, image: np.ndarray, boxes: np.ndarray) -> PoseBatch:
        return self._estimate(image, boxes, [None] * len(boxes))

    def estimate_in_rois(self, image: np.ndarray, rois: list[np.ndarray | None], boxes: np.ndarray) -> PoseBatch:
        """One pass per person on a given ROI (2x3 crop matrix); ``None`` falls back to the box."""
        return self._estimate(image, boxes, rois)

    def _estimate(self, image: np.ndarray, boxes: np.ndarray, rois: list) -> PoseBatch:
        n = len(boxes)
        keypoints = np.zeros((n, 17, 3), np.float32)
        feet = np.zeros((n, FEET, 3), np.float32)
        world = np.zeros((n, 33, 3), np.float32)
        matrices = [rois[i] if rois[i] is not None else self._first_crop(boxes[i])[0] for i in range(n)]
        results = self._run(image, matrices)  # every person's first (or only) pass in one call
        fresh = [i for i in range(n) if rois[i] is None]
        # Weak heatmaps on the upright crop: the body may be upside down or lying; try it turned.
        weak = [i for i in fresh if results[i][3] < self.orientation_check]
        turned = [(i, c) for i in weak for c in self._first_crop(boxes[i])[1:]]
        for (i, c), result in zip(turned, self._run(image, [c for _, c in turned])):
            if result[3] > results[i][3]:
                results[i], matrices[i] = result, c
        for _ in range(self.passes - 1):  # MediaPipe's ROI from the landmarks, then the pass kept
            for i in fresh:
                xy = to_image(results[i][0][:, :2].astype(np.float64), matrices[i])
                matrices[i] = roi_transform(xy[33], xy[34], self.size)
            for i, result in zip(fresh, self._run(image, [matrices[i] for i in fresh])):
                results[i] = result
        for i in range(n):
            self._fill(i, results[i], matrices[i], keypoints, feet, world)
        return PoseBatch(keypoints, feet, world)

    @staticmethod
    def _fill(i: int, result: tuple, m: np.ndarray, keypoints: np.ndarray, feet: np.ndarray,
              world: np.ndarray) -> None:
        landmarks, presence, world_raw, _ = result
        xy = to_image(landmarks[:, :2].astype(np.float64), m)
        score = _sigmoid(landmarks[:, 3]) * presence
        keypoints[i] = np.column_stack([xy[list(BLAZE_TO_COCO17)], score[list(BLAZE_TO_COCO17)]])
        feet[i] = np.column_stack([xy[list(BLAZE_FEET)], score[list(BLAZE_FEET)]])
        # World landmarks come in the crop's orientation; turn them back to the image's.
        rot = m[:, :2] / np.hypot(*m[0, :2])
        world[i] = np.column_stack([world_raw[:33, :2] @ rot, world_raw[:33, 2]])


def body_roi(keypoints: np.ndarray, size: int, min_score: float = 0.3) -> np.ndarray | None:
    """MediaPipe's pose ROI from a COCO-17 body: centred on the hips, up along the spine.

    The scale point lies along hips -> shoulders at the body's reach from the hip centre
    (the farthest confident joint) times 1.1; ``None`` without confident hips and shoulders.
    """
    kp = np.asarray(keypoints, np.float64)
    if (kp[[5, 6, 11, 12], 2] < min_score).any():
        return None
    hips, shoulders = kp[[11, 12], :2].mean(0), kp[[5, 6], :2].mean(0)
    spine = shoulders - hips
    length = float(np.hypot(*spine))
    if length < 1.0:
        return None
    good = kp[kp[:, 2] >= min_score, :2]
    reach = max(float(np.linalg.norm(good - hips, axis=1).max()), 1.5 * length) * 1.1
    return roi_transform(hips, hips + spine / length * reach, size)


class BodyAndFeet:
    """One model's body (COCO-17) with BlazePose's heels, toes and world landmarks.

    BlazePose runs once per person, on the ROI that the body model's hips and shoulders give
    (upside-down and lying dancers come out upright), or on the box's upright square when
    those are not confident. Each side's foot points are then moved by the difference between the two
    models' ankles of that side, so the feet hang from the body model's ankles (the foot's
    own shape is kept).
    """

    def __init__(self, body, feet: BlazePose) -> None:
        self.body, self.feet = body, feet

    def estimate(self, image: np.ndarray, boxes: np.ndarray) -> PoseBatch:
        return self.complete(image, boxes, self.body.estimate(image, boxes))

    def complete(self, image: np.ndarray, boxes: np.ndarray, body: PoseBatch) -> PoseBatch:
        """Add the feet to poses ``body`` already computed by the body model for ``boxes``."""
        size = self.feet.size
        # Without confident hips and shoulders (seated, cropped), one upright pass on the box: the
        # feet are rarely visible then, and the orientation search would cost four more passes.
        rois = [body_roi(kp, size) for kp in body.keypoints]
        rois = [roi if roi is not None else crop_transform(box, size, size, self.feet.padding)
                for roi, box in zip(rois, boxes)]
        feet = self.feet.estimate_in_rois(image, rois, boxes)
        moved = feet.feet.copy()
        for side, ankle in ((0, 15), (1, 16)):  # FOOT_POINTS: left heel, right heel, left toe, right toe
            shift = body.keypoints[:, ankle, :2] - feet.keypoints[:, ankle, :2]
            moved[:, [side, side + 2], :2] += shift[:, None, :]
        return PoseBatch(body.keypoints, moved, feet.world)
