"""Lifting 2D clips to 3D with an exported lifter in ONNX Runtime (no torch needed)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.motion.lifting.geometry import normalise
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
    """A lifter: an exported ONNX model (``from_session``, the lift stage's) or a torch model in
    training (``from_torch``); both lift clips the same way."""

    def __init__(self, forward: Callable[[np.ndarray], np.ndarray], receptive_field: int,
                 input_norm: str = "screen") -> None:
        self.forward = forward            # (1, T, 17, 2) float32 -> (1, T - rf + 1, 17, 3)
        self.receptive_field = receptive_field
        self.input_norm = input_norm      # how 2D keypoints are normalised (geometry.normalise)

    @classmethod
    def from_session(cls, session) -> Lifter:
        """An ONNX lifter exported by ``pipeline.motion.lifting.train.export_onnx`` (or the converter)."""
        meta = session.get_modelmeta().custom_metadata_map
        if "receptive_field" not in meta:
            raise ValueError("the lifter ONNX has no receptive_field in its metadata (export it with dance3d)")
        name = session.get_inputs()[0].name
        # Lifters exported before the centred normalisation, and converted official weights, are "screen".
        return cls(lambda x: session.run(None, {name: x})[0], int(meta["receptive_field"]),
                   meta.get("input_norm", "screen"))

    @classmethod
    def from_torch(cls, model, input_norm: str = "screen") -> Lifter:
        import torch

        def forward(x: np.ndarray) -> np.ndarray:
            model.eval()
            with torch.no_grad():
                return model(torch.from_numpy(x)).numpy()

        return cls(forward, model.receptive_field, input_norm)

    def _run(self, sequences: list[np.ndarray]) -> list[np.ndarray]:
        """Lift several normalised clips (T_i x 17 x 2) in one call: each is edge-padded by
        half the receptive field and the padded clips are laid end to end."""
        pad = self.receptive_field // 2
        padded = [np.concatenate([np.repeat(s[:1], pad, 0), s, np.repeat(s[-1:], pad, 0)]) for s in sequences]
        out = self.forward(np.concatenate(padded)[None].astype(np.float32))
        results, offset = [], 0
        for s in sequences:
            results.append(out[0, offset: offset + len(s)])
            offset += len(s) + 2 * pad
        return results

    def lift(self, clips: list[np.ndarray], width: int, height: int, *, flip: bool = False) -> list[np.ndarray]:
        """2D pixel clips (T_i x 17 x 2, COCO) -> 3D clips (T_i x 17 x 3, H36M, root-relative metres)."""
        if not clips:
            return []
        norm = [normalise(c, width, height, self.input_norm, self.receptive_field) for c in clips]
        outputs = self._run(norm)
        if flip:
            mirrored = [(n * np.array([-1.0, 1.0]))[:, list(COCO_FLIP)] for n in norm]
            back = [(o * np.array([-1.0, 1.0, 1.0]))[:, list(H36M_FLIP)] for o in self._run(mirrored)]
            outputs = [(a + b) / 2 for a, b in zip(outputs, back)]
        # Training targets have the root at 0, but the network only learns to come close.
        return [(o - o[:, :1]).astype(np.float32) for o in outputs]


# --- the lift stage's worker -------------------------------------------------------------

@dataclass(frozen=True)
class LiftJob:
    clean: Path
    out: Path
    min_score: float   # 2D joints below this are interpolated over time first
    flip: bool         # average with the mirrored input
    params: dict
    inputs: dict
    fingerprint: str


def load_lifter(path: str, threads: int = 1) -> Lifter:
    """One worker's lifter, built once and reused for every segment it gets."""
    from pipeline.pose.models.session import create_session

    return Lifter.from_session(create_session(Path(path), threads))


def lift_segment(lifter: Lifter, job: LiftJob) -> dict:
    """All clips of a segment in one ONNX call; writes the segment's 3D motion table."""
    from pipeline.annotate.clipfile import read_clean
    from pipeline.motion.motionfile import MotionClip, write_motion
    from pipeline.motion.trajectory import assumed_focal, root_from_2d

    clean = read_clean(job.clean)
    width, height = clean.segment.width, clean.segment.height
    filled = [fill_low_confidence(c.keypoints, job.min_score) for c in clean.clips]
    lifted = lifter.lift([f[0] for f in filled], width, height, flip=job.flip)
    focal = assumed_focal(width, height)
    roots = [root_from_2d(joints, f[0], focal, width, height, scores=c.keypoints[..., 2]).astype(np.float32)
             for c, joints, f in zip(clean.clips, lifted, filled)]
    clips = [MotionClip(c.clip_id, c.track_id, c.frame.astype(np.int32), clean.time(c), joints, c.interpolated,
                        f[1].sum(1).astype(np.int8), root)
             for c, joints, f, root in zip(clean.clips, lifted, filled, roots)]
    segment = {"segment_id": clean.segment.segment_id, "fps": clean.segment.fps, "width": clean.segment.width,
               "height": clean.segment.height}
    write_motion(job.out, clips, segment, fingerprint=job.fingerprint, params=job.params, inputs=job.inputs)
    return {"clips": len(clips), "frames": int(sum(len(c.frame) for c in clean.clips))}
