"""Lifting 2D clips to 3D with an exported lifter in ONNX Runtime (no torch needed)."""

from __future__ import annotations

import numpy as np

from pipeline.motion.lifting.geometry import normalise_screen
from pipeline.motion.mocap.skeleton import COCO_FLIP, H36M_FLIP


def fill_low_confidence(keypoints: np.ndarray, min_score: float) -> tuple[np.ndarray, np.ndarray]:
    """Replace joints below ``min_score`` by linear interpolation over time (held at the ends).

    Returns the filled (T x 17 x 2) positions and the T x 17 mask of filled joints. A joint
    never confident in the clip keeps its raw detections.
    """
    xy = keypoints[..., :2].astype(np.float64).copy()
    low = keypoints[..., 2] < min_score
    frames = np.arange(len(xy))
    for j in range(xy.shape[1]):
        good = ~low[:, j]
        if good.all() or not good.any():
            continue
        for c in range(2):
            xy[low[:, j], j, c] = np.interp(frames[low[:, j]], frames[good], xy[good, j, c])
    filled = low & low.any(0, keepdims=True) & (~low).any(0, keepdims=True)
    return xy, filled


class Lifter:
    """An ONNX lifter exported by ``pipeline.motion.lifting.train.export_onnx`` (or the converter)."""

    def __init__(self, session) -> None:
        self.session = session
        meta = session.get_modelmeta().custom_metadata_map
        if "receptive_field" not in meta:
            raise ValueError("the lifter ONNX has no receptive_field in its metadata (export it with dance3d)")
        self.receptive_field = int(meta["receptive_field"])
        self.input_name = session.get_inputs()[0].name

    def _run(self, sequences: list[np.ndarray]) -> list[np.ndarray]:
        """Lift several normalised clips (T_i x 17 x 2) in one call: each is edge-padded by
        half the receptive field and the padded clips are laid end to end."""
        pad = self.receptive_field // 2
        padded = [np.concatenate([np.repeat(s[:1], pad, 0), s, np.repeat(s[-1:], pad, 0)]) for s in sequences]
        (out,) = self.session.run(None, {self.input_name: np.concatenate(padded)[None].astype(np.float32)})
        results, offset = [], 0
        for s in sequences:
            results.append(out[0, offset: offset + len(s)])
            offset += len(s) + 2 * pad
        return results

    def lift(self, clips: list[np.ndarray], width: int, height: int, *, flip: bool = False) -> list[np.ndarray]:
        """2D pixel clips (T_i x 17 x 2, COCO) -> 3D clips (T_i x 17 x 3, H36M, root-relative metres)."""
        if not clips:
            return []
        norm = [normalise_screen(c, width, height) for c in clips]
        outputs = self._run(norm)
        if flip:
            mirrored = [(n * np.array([-1.0, 1.0]))[:, list(COCO_FLIP)] for n in norm]
            back = [(o * np.array([-1.0, 1.0, 1.0]))[:, list(H36M_FLIP)] for o in self._run(mirrored)]
            outputs = [(a + b) / 2 for a, b in zip(outputs, back)]
        # Training targets have the root at 0, but the network only learns to come close.
        return [(o - o[:, :1]).astype(np.float32) for o in outputs]
