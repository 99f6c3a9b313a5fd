"""Lifting 2D clips to 3D with an exported lifter in ONNX Runtime (no torch needed)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.motion.lifting.geometry import normalise
from pipeline.motion.mocap.skeleton import COCO21_FLIP, COCO_FLIP, FEET_ANKLES_COCO, H36M21_FLIP, H36M_FLIP

# ONNX metadata values of the joint sets (export_onnx writes them)
JOINTS_IN = {False: "coco17", True: "coco17+feet"}
JOINTS_OUT = {False: "h36m17", True: "h36m17+feet"}

# The 2D before lifting: the HP lambda at 30 fps (scaled by the fourth power of the rate at others).
# The lifter passes the pose model's frame-to-frame noise into the 3D, where HP at lambda 1 hardly
# touches it (docs/reports/world.md, 2026-12-05 (a fifth session)); chosen on the lifter split's
# training sequences.
DENOISE_2D = 10.0
DENOISE_FPS = 30.0


@dataclass(frozen=True)
class LiftOptions:
    """How 2D clips are lifted (params.yaml ``lift``): what the lift stage does and what
    ``dance3d eval world`` and ``eval group`` run on filmed motion capture."""
    min_score: float = 0.3       # 2D joints below this confidence are interpolated over time first
    flip: bool = True            # average with the mirrored input
    denoise: float = DENOISE_2D  # HP lambda as at 30 fps on the 2D before lifting (0: none)

    @classmethod
    def from_params(cls, lift: Mapping) -> LiftOptions:
        # A project whose params.yaml predates lift.denoise_2d keeps its 2D as it was made.
        return cls(float(lift.get("min_score", cls.min_score)), bool(lift.get("flip_tta", cls.flip)),
                   float(lift.get("denoise_2d", 0.0)))


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


def denoise_2d(xy: np.ndarray, fps: float, lamb: float = DENOISE_2D) -> np.ndarray:
    """2D keypoint paths (T x J x 2, pixels) HP-filtered along time with ``lamb`` as at 30 fps
    (0: unchanged): the pose model's frame-to-frame noise out, the dancer's motion kept."""
    if lamb <= 0 or len(xy) < 3 or not np.isfinite(xy).all():  # a NaN would spread along the whole series
        return xy
    from pipeline.motion.smoothing import hp_lambda_at, hp_trend

    return hp_trend(xy, hp_lambda_at(lamb, fps, DENOISE_FPS))


class Lifter:
    """A lifter: an exported ONNX model (``from_session``, the lift stage's) or a torch model in
    training (``from_torch``); both lift clips the same way."""

    def __init__(self, forward: Callable[[np.ndarray], np.ndarray], receptive_field: int,
                 input_norm: str = "screen", feet: bool = False) -> None:
        self.forward = forward            # (1, T, J, 2) float32 -> (1, T - rf + 1, J, 3); J = 17, or 21 with feet
        self.receptive_field = receptive_field
        self.input_norm = input_norm      # how 2D keypoints are normalised (geometry.normalise)
        self.feet = feet                  # takes and returns heels and toe tips after the 17 joints

    @classmethod
    def from_session(cls, session) -> Lifter:
        """An ONNX lifter exported by ``pipeline.motion.lifting.train.export_onnx`` (or the converter)."""
        meta = session.get_modelmeta().custom_metadata_map
        if "receptive_field" not in meta:
            raise ValueError("the lifter ONNX has no receptive_field in its metadata (export it with dance3d)")
        name = session.get_inputs()[0].name
        # Lifters exported before the centred normalisation, and converted official weights, are "screen".
        return cls(lambda x: session.run(None, {name: x})[0], int(meta["receptive_field"]),
                   meta.get("input_norm", "screen"), meta.get("joints_in", "coco17") == JOINTS_IN[True])

    @classmethod
    def from_torch(cls, model, input_norm: str = "screen") -> Lifter:
        import torch

        def forward(x: np.ndarray) -> np.ndarray:
            model.eval()
            with torch.no_grad():
                return model(torch.from_numpy(x)).numpy()

        return cls(forward, model.receptive_field, input_norm, model.joints_in == 21)

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
        """2D pixel clips (T_i x 17 x 2, COCO) -> 3D clips (T_i x 17 x 3, H36M, root-relative metres);
        21 joints in and out for a lifter with feet (heels and toe tips after the body)."""
        if not clips:
            return []
        norm = [normalise(c, width, height, self.input_norm, self.receptive_field) for c in clips]
        outputs = self._run(norm)
        if flip:
            flip_in, flip_out = (COCO21_FLIP, H36M21_FLIP) if self.feet else (COCO_FLIP, H36M_FLIP)
            mirrored = [(n * np.array([-1.0, 1.0]))[:, list(flip_in)] for n in norm]
            back = [(o * np.array([-1.0, 1.0, 1.0]))[:, list(flip_out)] for o in self._run(mirrored)]
            outputs = [(a + b) / 2 for a, b in zip(outputs, back)]
        # Training targets have the root at 0, but the network only learns to come close.
        return [(o - o[:, :1]).astype(np.float32) for o in outputs]


def with_feet(keypoints: np.ndarray, feet: np.ndarray) -> np.ndarray:
    """COCO-17 keypoints and the heels and toes after them (T x 21 x 3, x, y, score). A foot point
    the pose model never saw in the clip (a model without feet gives score 0) stands at its
    ankle, scored 0: the lifter gets a foot of no length rather than the image's corner."""
    feet = feet.astype(np.float64).copy()
    for k, ankle in enumerate(FEET_ANKLES_COCO):
        if not (feet[:, k, 2] > 0).any():
            feet[:, k, :2], feet[:, k, 2] = keypoints[:, ankle, :2], 0.0
    return np.concatenate([keypoints.astype(np.float64), feet], 1)


# --- the lift stage's worker -------------------------------------------------------------

@dataclass(frozen=True)
class LiftModels:
    """What a lift worker loads once: the lifter, and the contact model (None: no learned contact)."""
    lifter: Lifter
    contact: object | None = None  # pipeline.motion.world.contact_model.ContactModel


@dataclass(frozen=True)
class LiftedClip:
    joints: np.ndarray        # T x 17 x 3 root-relative, camera frame
    feet: np.ndarray | None   # T x 4 x 3 like joints (None: the lifter has no feet)
    root: np.ndarray          # T x 3 the per-frame root path, camera frame (trajectory.root_from_2d)
    contact: np.ndarray | None  # T x 4 contact probabilities of the heels and toe tips (None: no contact model)
    filled: np.ndarray        # T x 17 2D joints filled because their confidence was low
    feet_rays: np.ndarray | None = None  # T x 4 x 3 where the heels and toe tips are seen (None: no 2D feet)


@dataclass(frozen=True)
class LiftJob:
    clean: Path
    out: Path
    opts: LiftOptions
    params: dict
    inputs: dict
    fingerprint: str


def load_models(lifter: str, contact: str = "", threads: int = 1) -> LiftModels:
    """One worker's models, built once and reused for every segment it gets."""
    from pipeline.motion.world.contact_model import load_contact_model

    return LiftModels(load_lifter(lifter, threads), load_contact_model(Path(contact), threads) if contact else None)


def load_lifter(path: str, threads: int = 1) -> Lifter:
    from pipeline.pose.models.session import create_session

    return Lifter.from_session(create_session(Path(path), threads))


def lift_clips(models: LiftModels, keypoints: list[np.ndarray], feet: list[np.ndarray | None], width: int,
               height: int, fps: float, opts: LiftOptions = LiftOptions()) -> list[LiftedClip]:
    """2D clips (T x 17 x 3 pixels and scores; heels and toes T x 4 x 3 or None) -> 3D, the root's
    path and the contact probabilities: what the lift stage writes, and what ``dance3d eval world``
    runs on filmed motion capture. The 2D is filled where unsure, then denoised (``denoise_2d``)."""
    from pipeline.motion.world.trajectory import assumed_focal, place_root, sight_rays

    if not keypoints:
        return []
    lifter = models.lifter
    full = [with_feet(k, f if f is not None else np.zeros((len(k), 4, 3))) for k, f in zip(keypoints, feet)]
    filled = [(denoise_2d(xy, fps, opts.denoise), mask)
              for xy, mask in (fill_low_confidence(k, opts.min_score) for k in full)]
    inputs = [f[0] if lifter.feet else f[0][:, :17] for f in filled]
    lifted = lifter.lift(inputs, width, height, flip=opts.flip)
    focal = assumed_focal(width, height)
    out = []
    for seen, joints, (xy, mask), heels_toes in zip(full, lifted, filled, feet):
        n = joints.shape[1]  # 21 for a lifter with feet: its heels and toe tips help place it
        joints, root = place_root(joints, xy[:, :n], focal, width, height, scores=seen[:, :n, 2])
        contact = None if models.contact is None else models.contact.probabilities(xy, fps, flip=opts.flip)
        rays = None if heels_toes is None else sight_rays(xy[:, 17:21], focal, width, height).astype(np.float32)
        out.append(LiftedClip(joints[:, :17], joints[:, 17:] if lifter.feet else None, root.astype(np.float32),
                              contact, mask[:, :17], rays))
    return out


def clip_hands(clip) -> tuple[np.ndarray | None, np.ndarray | None]:
    """A clean clip's hands as the motion files carry them (``pipeline.motion.hands.hand_shapes``):
    wrist-relative metric shapes and each hand's presence; (None, None) without hands."""
    from pipeline.motion.hands import hand_shapes

    if clip.hands_world is None:
        return None, None
    return hand_shapes(clip.hands_world, clip.hand_presence)


def lift_segment(models: LiftModels, job: LiftJob) -> dict:
    """All clips of a segment in one ONNX call; writes the segment's 3D motion table."""
    from pipeline.annotate.clipfile import read_clean
    from pipeline.motion.motionfile import MotionClip, write_motion

    clean = read_clean(job.clean)
    lifted = lift_clips(models, [c.keypoints for c in clean.clips], [c.feet for c in clean.clips],
                        clean.segment.width, clean.segment.height, clean.segment.fps, job.opts)
    clips = [MotionClip(c.clip_id, c.track_id, c.frame.astype(np.int32), clean.time(c), lc.joints,
                        c.interpolated, lc.filled.sum(1).astype(np.int8), lc.root, lc.feet, lc.contact, lc.feet_rays,
                        *clip_hands(c))
             for c, lc in zip(clean.clips, lifted)]
    segment = {"segment_id": clean.segment.segment_id, "fps": clean.segment.fps, "width": clean.segment.width,
               "height": clean.segment.height}
    write_motion(job.out, clips, segment, fingerprint=job.fingerprint, params=job.params, inputs=job.inputs)
    return {"clips": len(clips), "frames": int(sum(len(c.frame) for c in clean.clips))}
