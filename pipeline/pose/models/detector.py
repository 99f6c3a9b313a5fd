"""Person detection with RTMDet end2end exports (NMS inside the graph)."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.pose.models.normalize import IMAGENET, InputTable

# mmdet's test pipeline for RTMDet: BGR input, these means and stds in B, G, R order.
MEAN_BGR = np.array([103.53, 116.28, 123.675], np.float32)
STD_BGR = np.array([57.375, 57.12, 58.395], np.float32)
RTMDET_INPUT = InputTable(tuple(MEAN_BGR), tuple(STD_BGR))
PAD_VALUE = 114


@dataclass(frozen=True)
class Letterbox:
    tensor: np.ndarray   # 1x3xHxW float32
    scale: float         # model pixels per image pixel
    width: int           # original image size
    height: int


@dataclass(frozen=True)
class Detections:
    boxes: np.ndarray    # Nx4 float32 x1, y1, x2, y2 in image pixels, clipped
    scores: np.ndarray   # N float32

    def __len__(self) -> int:
        return len(self.scores)


def letterbox(image: np.ndarray, size: tuple[int, int] = (320, 320)) -> Letterbox:
    """Resize keeping the aspect ratio, pad right and bottom with 114, normalise, NCHW."""
    h, w = image.shape[:2]
    width, height = size
    scale = min(width / w, height / h)
    new_w, new_h = int(round(w * scale)), int(round(h * scale))
    canvas = np.full((height, width, 3), PAD_VALUE, np.uint8)
    canvas[:new_h, :new_w] = cv2.resize(image, (new_w, new_h), interpolation=cv2.INTER_LINEAR)
    return Letterbox(RTMDET_INPUT(canvas), scale, w, h)


def decode_dets(dets: np.ndarray, box: Letterbox, score_threshold: float) -> Detections:
    """Model output rows (x1, y1, x2, y2, score) -> image-pixel boxes above the threshold."""
    rows = dets.reshape(-1, 5)
    rows = rows[rows[:, 4] >= score_threshold]
    boxes = rows[:, :4] / box.scale
    boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, box.width)
    boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, box.height)
    return Detections(boxes.astype(np.float32), rows[:, 4].astype(np.float32))


def largest(dets: Detections, k: int) -> Detections:
    """The ``k`` largest boxes (by area), largest first; ties keep the higher score first."""
    area = (dets.boxes[:, 2] - dets.boxes[:, 0]) * (dets.boxes[:, 3] - dets.boxes[:, 1])
    order = np.lexsort((-dets.scores, -area))[:k]
    return Detections(dets.boxes[order], dets.scores[order])


class RTMDetDetector:
    """Wraps an ONNX Runtime session of an RTMDet end2end export."""

    def __init__(self, session, input_size: tuple[int, int] = (320, 320), score_threshold: float = 0.5):
        self.session = session
        self.input_size = input_size
        self.score_threshold = score_threshold
        self.input_name = session.get_inputs()[0].name
        self.output_name = session.get_outputs()[0].name

    def preprocess(self, image: np.ndarray) -> Letterbox:
        return letterbox(image, self.input_size)

    def infer(self, box: Letterbox) -> Detections:
        (dets,) = self.session.run([self.output_name], {self.input_name: box.tensor})
        return decode_dets(dets[0], box, self.score_threshold)

    def detect(self, image: np.ndarray) -> Detections:
        return self.infer(self.preprocess(image))




def nms(boxes: np.ndarray, scores: np.ndarray, iou: float) -> np.ndarray:
    """Indices kept by greedy non-maximum suppression (OpenCV's), highest score first."""
    if not len(boxes):
        return np.zeros(0, int)
    xywh = [[float(x1), float(y1), float(x2 - x1), float(y2 - y1)] for x1, y1, x2, y2 in boxes]
    keep = cv2.dnn.NMSBoxes(xywh, [float(s) for s in scores], 0.0, iou)
    keep = np.asarray(keep, int).reshape(-1)
    return keep[np.argsort(-scores[keep], kind="stable")]


class PicoDetDetector:
    """PicoDet exports without NMS in the graph (plain resize, RGB, ImageNet-normalised, 320x320)."""

    def __init__(self, session, input_size: tuple[int, int] = (320, 320), score_threshold: float = 0.5,
                 nms_iou: float = 0.6):
        self.session = session
        self.input_size = input_size
        self.score_threshold = score_threshold
        self.nms_iou = nms_iou
        self.input_name = session.get_inputs()[0].name
        shapes = {o.name: o.shape for o in session.get_outputs()}
        self.boxes_name = next(n for n, s in shapes.items() if s[-1] == 4)
        self.scores_name = next(n for n in shapes if n != self.boxes_name)

    def preprocess(self, image: np.ndarray) -> tuple[np.ndarray, int, int]:
        h, w = image.shape[:2]
        width, height = self.input_size
        return IMAGENET(cv2.resize(image, (width, height), interpolation=cv2.INTER_LINEAR)), w, h

    def detect(self, image: np.ndarray) -> Detections:
        return self.infer(self.preprocess(image))

    def infer(self, prepared: tuple[np.ndarray, int, int]) -> Detections:
        tensor, w, h = prepared
        width, height = self.input_size
        boxes, scores = self.session.run([self.boxes_name, self.scores_name], {self.input_name: tensor})
        boxes, scores = boxes.reshape(-1, 4), scores.reshape(-1)
        good = scores >= self.score_threshold
        boxes, scores = boxes[good] * np.array([w / width, h / height] * 2, np.float32), scores[good]
        boxes[:, [0, 2]] = boxes[:, [0, 2]].clip(0, w)
        boxes[:, [1, 3]] = boxes[:, [1, 3]].clip(0, h)
        keep = nms(boxes, scores, self.nms_iou)
        return Detections(boxes[keep].astype(np.float32), scores[keep].astype(np.float32))


class FusedDetector:
    """Several detectors on the same frame, their boxes merged by NMS: they miss different people."""

    def __init__(self, detectors: list, nms_iou: float = 0.5):
        self.detectors = detectors
        self.nms_iou = nms_iou

    def preprocess(self, image: np.ndarray) -> tuple:
        return tuple(d.preprocess(image) for d in self.detectors)

    def detect(self, image: np.ndarray) -> Detections:
        return self.infer(self.preprocess(image))

    def infer(self, prepared: tuple) -> Detections:
        found = [d.infer(x) for d, x in zip(self.detectors, prepared)]
        boxes = np.concatenate([f.boxes for f in found]).reshape(-1, 4)
        scores = np.concatenate([f.scores for f in found])
        keep = nms(boxes, scores, self.nms_iou)
        return Detections(boxes[keep], scores[keep])
