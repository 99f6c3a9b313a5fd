"""Learned foot contact: the probability that each heel and toe tip is planted, from the 2D keypoints.

A static camera sees a planted foot stand still in the image, and a pose model's per-frame noise
hides that only over a few frames; so the model looks at ``2 * HALF + 1`` frames (1.2 s at
``FPS``) of the 21 keypoints (COCO-17, heels, toe tips) around each frame, expressed about that
frame's hips and divided by that frame's body size (``features``): where the feet go relative to
the body, and how the body moves in the image. A small network (``contact_train.ContactNet``)
scores the four points of the centre frame. Trained on motion capture filmed by the lifter's
virtual cameras, with labels from the capture's own feet (``contact.capture_contact``).

Runs in ONNX Runtime (no torch): clips at other rates are resampled to ``FPS`` and back.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from pipeline.motion.lifting.geometry import body_size
from pipeline.motion.mocap.skeleton import COCO21_FLIP
from pipeline.motion.resample import interpolate_linear

FPS = 25.0        # the model's frame rate (the lifter's training rate)
HALF = 15         # frames each side of the scored frame
FLIP_OUT = (1, 0, 3, 2)  # heels and toes, left and right swapped (skeleton.FEET order)


def features(xy: np.ndarray, centres: np.ndarray | None = None) -> np.ndarray:
    """Keypoints (T x 21 x 2, pixels) -> one input per centre frame (N x (2 HALF + 1) x 21 x 2):
    the frames around it (edge-padded) about its hips, divided by its body size."""
    xy = np.asarray(xy, np.float64)
    centres = np.arange(len(xy)) if centres is None else np.asarray(centres)
    size = np.maximum(body_size(xy, 2 * HALF + 1), 1e-6)
    hips = (xy[:, 11] + xy[:, 12]) / 2
    padded = np.concatenate([np.repeat(xy[:1], HALF, 0), xy, np.repeat(xy[-1:], HALF, 0)])
    idx = centres[:, None] + np.arange(2 * HALF + 1)[None]
    out = (padded[idx] - hips[centres][:, None, None]) / size[centres][:, None, None, None]
    return out.astype(np.float32)


def resample_keypoints(xy: np.ndarray, fps: float, rate: float = FPS) -> tuple[np.ndarray, np.ndarray]:
    """Keypoints (T x J x 2) at ``fps`` -> (keypoints at ``rate``, their times in source frames)."""
    if abs(fps - rate) < 1e-6 or len(xy) < 2:
        return xy, np.arange(len(xy), dtype=np.float64)
    at = np.arange(0, len(xy) - 1 + 1e-9, fps / rate)
    return interpolate_linear(at, np.arange(len(xy)), xy), at


class ContactModel:
    """A contact model: an exported ONNX model (``from_session``) or a torch model in training
    (``from_torch``); both score clips the same way."""

    def __init__(self, forward: Callable[[np.ndarray], np.ndarray], batch: int = 4096) -> None:
        self.forward = forward  # (N, 2 HALF + 1, 21, 2) float32 -> (N, 4) logits
        self.batch = batch

    @classmethod
    def from_session(cls, session) -> ContactModel:
        meta = session.get_modelmeta().custom_metadata_map
        if int(meta.get("half_window", -1)) != HALF or float(meta.get("fps", 0)) != FPS:
            raise ValueError(f"the contact model's window ({meta.get('half_window')} frames each side at "
                             f"{meta.get('fps')} fps) is not this code's ({HALF} at {FPS:g})")
        name = session.get_inputs()[0].name
        return cls(lambda x: session.run(None, {name: x})[0])

    @classmethod
    def from_torch(cls, model) -> ContactModel:
        import torch

        def forward(x: np.ndarray) -> np.ndarray:
            model.eval()
            with torch.no_grad():
                return model(torch.from_numpy(x)).numpy()

        return cls(forward)

    def _logits(self, xy: np.ndarray) -> np.ndarray:
        out = []
        for start in range(0, len(xy), self.batch):
            out.append(self.forward(features(xy, np.arange(start, min(len(xy), start + self.batch)))))
        return np.concatenate(out) if out else np.zeros((0, 4), np.float32)

    def probabilities(self, keypoints: np.ndarray, fps: float, *, flip: bool = True) -> np.ndarray:
        """Keypoints (T x 21 x 2 pixels: COCO-17, heels, toe tips) at ``fps`` -> T x 4 probabilities
        that the left heel, right heel, left toe tip, right toe tip are planted. ``flip`` averages
        with the mirrored clip (left and right swapped back), as the lifter does."""
        xy = np.asarray(keypoints, np.float64)[..., :2]
        if not len(xy):
            return np.zeros((0, 4), np.float32)
        at_rate, times = resample_keypoints(xy, fps)
        logits = self._logits(at_rate)
        if flip:
            mirrored = (at_rate * np.array([-1.0, 1.0]))[:, list(COCO21_FLIP)]
            logits = (logits + self._logits(mirrored)[:, list(FLIP_OUT)]) / 2
        prob = 1 / (1 + np.exp(-logits.astype(np.float64)))
        return interpolate_linear(np.arange(len(xy), dtype=np.float64), times, prob).astype(np.float32)


def load_contact_model(path: Path, threads: int = 1) -> ContactModel:
    from pipeline.pose.models.session import create_session

    return ContactModel.from_session(create_session(Path(path), threads))
