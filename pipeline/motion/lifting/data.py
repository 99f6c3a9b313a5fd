"""2D/3D training pairs from motion capture through random virtual cameras, with
augmentations that mimic what a detector and a video do to keypoints.

For a window of a mocap sequence: scale the body (bone-length / height variety),
optionally mirror it, place a camera at a random distance, height, yaw and pitch looking
at the dancer, project the COCO-17 keypoints into a random image size with a random
focal length, then jitter joints, drop some (a dropped joint is carried over from the
previous frame, as the lift stage's gap filling does) and swap a left/right pair for a
few frames. The target is the H36M-17 pose in camera coordinates, root-relative, metres.
With ``feet``, the heels and toe tips follow the 17 joints in both (``skeleton.FEET``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from pipeline.motion.lifting.evaluate import add_pose_noise
from pipeline.motion.lifting.geometry import look_at, normalise, project, to_camera
from pipeline.motion.mocap.skeleton import COCO21_FLIP, COCO_FLIP, H36M21_FLIP, H36M_FLIP
from pipeline.motion.mocap.sources import MocapSequence, keypoints_and_joints

IMAGE_SIZES = ((1280, 720), (720, 1280), (1920, 1080), (1080, 1920), (640, 480), (768, 576), (384, 496), (640, 360))
LR_PAIRS = ((5, 6), (7, 8), (9, 10), (11, 12), (13, 14), (15, 16))
FEET_LR_PAIRS = ((17, 18), (19, 20))


@dataclass(frozen=True)
class AugmentOptions:
    distance: tuple[float, float] = (2.5, 9.0)     # camera to dancer, m
    height: tuple[float, float] = (0.3, 2.5)       # camera height, m
    pitch_target: tuple[float, float] = (0.6, 1.4)  # height of the look-at point, m
    fill: tuple[float, float] = (0.2, 0.95)        # person height as a share of the image height
    scale: tuple[float, float] = (0.85, 1.15)      # body scale (bone-length variety)
    speed: tuple[float, float] = (0.75, 1.33)      # temporal speed change
    mirror: float = 0.5                            # probability of a mirrored body
    jitter: float = 0.012                          # joint noise, share of body height in the image (std)
    pose_noise: tuple[float, float] = (0.0, 0.5)   # per-joint pose-model noise (COCO sigmas), level drawn per window
                                                   # (0.5: expected OKS 0.80; see evaluate.add_pose_noise)
    drop: float = 0.03                             # probability a joint is missing in a frame
    swap: float = 0.02                             # probability per window of a left/right pair swapped for a while


def _window(sources: tuple[np.ndarray, np.ndarray], length: int, speed: float,
            start: float) -> tuple[np.ndarray, np.ndarray]:
    """``length`` frames from ``start`` (in source frames) stepping ``speed`` frames, linear interpolation."""
    frames = len(sources[0])
    idx = start + np.arange(length) * speed
    idx = np.clip(idx, 0, frames - 1)
    lo = np.floor(idx).astype(int)
    hi = np.minimum(lo + 1, frames - 1)
    w = (idx - lo)[:, None, None]
    coco, h36m = sources
    return coco[lo] * (1 - w) + coco[hi] * w, h36m[lo] * (1 - w) + h36m[hi] * w


@dataclass(frozen=True)
class Filmed:
    """One window of motion capture as a virtual camera saw it."""
    xy: np.ndarray        # length x J x 2 keypoints in pixels (augmented: jitter, pose noise, drops, swaps)
    width: int
    height: int
    world: np.ndarray     # length x J x 3 the same keypoints in the world (y up), after scale and mirror
    h36m_cam: np.ndarray  # length x J x 3 H36M joints (and feet) in the camera frame
    scale: float          # body scale applied about ``centre``
    centre: np.ndarray    # 3, the point the body was scaled (and mirrored) about


def film(seq: MocapSequence, length: int, rng: np.random.Generator, opts: AugmentOptions,
         augment: bool = True, feet: bool = False) -> Filmed:
    """A random window of ``seq`` through a random camera: COCO-17 keypoints (21 with ``feet``) in
    pixels, as a pose model would give them."""
    speed = rng.uniform(*opts.speed) if augment else 1.0
    span = (length - 1) * speed
    start = rng.uniform(0, max(0.0, seq.frames - 1 - span))
    coco, h36m = _window(keypoints_and_joints(seq, feet), length, speed, start)
    centre = h36m[:, 0].mean(0)
    scale = rng.uniform(*opts.scale) if augment else 1.0
    coco = (coco - centre) * scale + centre
    h36m = (h36m - centre) * scale + centre
    if augment and rng.random() < opts.mirror:
        flip = np.array([-1.0, 1.0, 1.0])
        coco = ((coco - centre) * flip + centre)[:, list(COCO21_FLIP if feet else COCO_FLIP)]
        h36m = ((h36m - centre) * flip + centre)[:, list(H36M21_FLIP if feet else H36M_FLIP)]
    body = np.ptp(h36m[:, :17, 1]) if np.ptp(h36m[:, :17, 1]) > 0.3 else 1.6
    for attempt in range(20):
        width, height = IMAGE_SIZES[rng.integers(len(IMAGE_SIZES))]
        yaw = rng.uniform(0, 2 * np.pi)
        # A dancer who travels during the window must stay in front of the camera and in view:
        # later attempts move the camera further away.
        distance = rng.uniform(*opts.distance) * (1 + 0.25 * attempt)
        cam_pos = centre + np.array([np.sin(yaw) * distance, 0.0, np.cos(yaw) * distance])
        cam_pos[1] = rng.uniform(*opts.height)
        target = np.array([centre[0], rng.uniform(*opts.pitch_target), centre[2]])
        rotation = look_at(cam_pos, target)
        coco_cam = to_camera(coco, rotation, cam_pos)
        h36m_cam = to_camera(h36m, rotation, cam_pos)
        focal = rng.uniform(*opts.fill) * height * distance / body
        xy = project(coco_cam, focal, width, height)
        inside = (xy > -0.25 * np.array([width, height])) & (xy < 1.25 * np.array([width, height]))
        if coco_cam[..., 2].min() > 1.0 and inside.all():
            break
    if augment:
        px_body = focal * body / distance
        xy = xy + rng.normal(0, opts.jitter * px_body, xy.shape)
        if opts.pose_noise[1] > 0:
            xy = add_pose_noise(xy, rng, rng.uniform(*opts.pose_noise), drop=0.0)
        if rng.random() < opts.swap:
            pairs = LR_PAIRS + FEET_LR_PAIRS if feet else LR_PAIRS
            a, b = pairs[rng.integers(len(pairs))]
            t0 = rng.integers(length)
            t1 = min(length, t0 + rng.integers(1, 8))
            xy[t0:t1, [a, b]] = xy[t0:t1, [b, a]]
        dropped = rng.random(xy.shape[:2]) < opts.drop
        for t in range(1, length):
            xy[t, dropped[t]] = xy[t - 1, dropped[t]]
    return Filmed(xy, width, height, coco, h36m_cam, scale, centre)


def make_pair(seq: MocapSequence, length: int, rng: np.random.Generator, opts: AugmentOptions,
              augment: bool = True, input_norm: str = "screen", window: int = 27,
              feet: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """One (2D input (length x 17 x 2), 3D target (length x 17 x 3)) pair (21 joints each with
    ``feet``); ``window`` is the receptive field (the centred normalisation's scale filter)."""
    shot = film(seq, length, rng, opts, augment, feet)
    inputs = normalise(shot.xy, shot.width, shot.height, input_norm, window).astype(np.float32)
    targets = (shot.h36m_cam - shot.h36m_cam[:, :1]).astype(np.float32)
    return inputs, targets


class PairSampler:
    """Random training windows, sequences drawn in proportion to their length times their
    source's weight (``weights``: source -> factor, 1 where unnamed).

    Batch ``step`` draws from its own generator, seeded by (seed, step): the data a step sees
    does not depend on the steps before it, so training resumed at any step sees what an
    uninterrupted run would."""

    def __init__(self, sequences: list[MocapSequence], length: int, opts: AugmentOptions, seed: int,
                 input_norm: str = "screen", window: int = 27, feet: bool = False,
                 weights: Mapping[str, float] | None = None) -> None:
        self.sequences = [s for s in sequences if s.frames >= 2]
        self.feet = feet
        weights = weights or {}
        frames = np.array([s.frames * weights.get(s.source, 1.0) for s in self.sequences], float)
        self.p = frames / frames.sum()
        self.length, self.opts = length, opts
        self.input_norm, self.window = input_norm, window
        self.seed = seed

    def share(self) -> dict[str, float]:
        """Each source's share of the windows drawn."""
        shares: dict[str, float] = {}
        for seq, p in zip(self.sequences, self.p):
            shares[seq.source] = shares.get(seq.source, 0.0) + float(p)
        return shares

    def batch(self, size: int, step: int) -> tuple[np.ndarray, np.ndarray]:
        rng = np.random.default_rng((self.seed, step))
        picks = rng.choice(len(self.sequences), size=size, p=self.p)
        pairs = [make_pair(self.sequences[i], self.length, rng, self.opts, input_norm=self.input_norm,
                           window=self.window, feet=self.feet) for i in picks]
        return np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs])
