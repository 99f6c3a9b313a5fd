"""Adapting a trained lifter to dance video: VideoPose3D's semi-supervised recipe (Pavllo et al.,
CVPR 2019, section 4) on the 2D the pipeline itself makes.

Every step trains on a batch of capture windows (the supervised loss of training) and a batch of
windows of real clips' 2D, which have no 3D. For those, the lifted pose, projected back, must land
on the 2D it was lifted from, and its mean bone lengths must match the capture's (VideoPose3D's
bone-length prior: without it, the projection alone lets the body shrink or stretch in depth).

Two departures from VideoPose3D, both because dance3d's lifter sees person-centred 2D
(``geometry.normalise_centred``): the projection is weak perspective onto that centred 2D, with
each frame's scale and offset solved in closed form (confidence-weighted least squares) where
VideoPose3D trains a trajectory model; and the 2D points compared are those both skeletons share
(``skeleton.COCO_H36M_SHARED``, COCO's hips placed as the capture's 2D places them, and the heels
and toe tips).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from pipeline.motion.lifting.geometry import normalise_centred
from pipeline.motion.lifting.infer import fill_low_confidence, with_feet
from pipeline.motion.mocap.skeleton import COCO21_FLIP, COCO_H36M_SHARED, FOOT_BONES, H36M_BONES, HIP_WIDENING

# The 2D points (COCO-17 + feet) whose 3D counterparts the lifter returns (H36M-17 + feet).
SHARED_COCO = [c for c, _ in COCO_H36M_SHARED] + [17, 18, 19, 20]
SHARED_H36M = [h for _, h in COCO_H36M_SHARED] + [17, 18, 19, 20]
BONES = H36M_BONES + FOOT_BONES


@dataclass(frozen=True)
class AdaptConfig:
    steps: int = 1000
    batch: int = 64                    # capture windows per step (the supervised loss)
    video_batch: int = 64              # windows of real 2D per step
    lr: float = 1e-4                   # a tenth of training's start: the lifter is only nudged
    lr_final: float = 1e-5
    reprojection_weight: float = 1.0   # 0 (with bone_weight 0): the supervised control
    bone_weight: float = 1.0
    velocity_weight: float = 0.0       # the capture's velocity error (MPJVE) beside its MPJPE: less jitter
    seed: int = 1
    threads: int = 2


@dataclass(frozen=True)
class VideoClip:
    """One dancer's 2D in a real clip, as the lift stage would give it to the lifter."""
    name: str
    xy: np.ndarray       # T x 21 x 2 pixels (COCO-17, heels, toe tips), low-confidence joints filled
    weight: np.ndarray   # T x 21 the keypoint confidence, 0 where filled
    fps: float           # the segment's frame rate


def video_clips(clean_files: list[Path], min_score: float = 0.3, min_frames: int = 25) -> list[VideoClip]:
    """The clips of the clean files (``data/clean``) with at least ``min_frames`` frames; 2D joints
    under ``min_score`` (the lift stage's default) are filled over time and weigh nothing."""
    from pipeline.annotate.clipfile import read_clean

    clips = []
    for path in clean_files:
        clean = read_clean(path)
        for clip in clean.clips:
            if len(clip.frame) < min_frames:
                continue
            full = with_feet(clip.keypoints, clip.feet)
            xy, _ = fill_low_confidence(full, min_score)
            weight = np.where(full[..., 2] >= min_score, full[..., 2], 0.0)
            clips.append(VideoClip(f"{clean.segment.segment_id}/{clip.clip_id}", xy, weight, clean.segment.fps))
    return clips


class VideoSampler:
    """Random windows of real clips, drawn in proportion to their length, half of them mirrored;
    each step's windows from a generator seeded by (seed, step), as the capture's."""

    def __init__(self, clips: list[VideoClip], length: int, receptive_field: int, seed: int) -> None:
        self.clips = [c for c in clips if len(c.xy) >= 2]
        if not self.clips:
            raise ValueError("no video clips to adapt on")
        frames = np.array([len(c.xy) for c in self.clips], float)
        self.p = frames / frames.sum()
        self.length, self.rf, self.seed = length, receptive_field, seed

    def batch(self, size: int, step: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Inputs (size x length x 21 x 2, centred), and for the middle frames the lifter returns,
        the 2D targets (size x chunk x 21 x 2, the same centred 2D) and their weights."""
        rng = np.random.default_rng((self.seed, step))
        pad = self.rf // 2
        chunk = self.length - self.rf + 1
        inputs, weights = [], []
        for i in rng.choice(len(self.clips), size=size, p=self.p):
            clip = self.clips[i]
            start = int(rng.integers(-pad, max(-pad + 1, len(clip.xy) - self.length + pad + 1)))
            idx = np.clip(np.arange(start, start + self.length), 0, len(clip.xy) - 1)  # edge-padded as lift pads
            xy, w = normalise_centred(clip.xy[idx], self.rf), clip.weight[idx]
            if rng.random() < 0.5:
                xy, w = (xy * np.array([-1.0, 1.0]))[:, list(COCO21_FLIP)], w[:, list(COCO21_FLIP)]
            inputs.append(xy)
            weights.append(w)
        inputs, weights = np.stack(inputs).astype(np.float32), np.stack(weights).astype(np.float32)
        return inputs, inputs[:, pad: pad + chunk], weights[:, pad: pad + chunk]


def projected_points(pose: torch.Tensor) -> torch.Tensor:
    """The lifted pose's points that the 2D has too (... x 21 x 3 -> ... x 16 x 3), hips widened."""
    points = pose[..., SHARED_H36M, :]
    pelvis = pose[..., :1, :]
    hips = pelvis + HIP_WIDENING * (points[..., 6:8, :] - pelvis)  # COCO 11, 12 are H36M 4, 1 widened
    return torch.cat([points[..., :6, :], hips, points[..., 8:, :]], -2)


def reprojection_error(pose: torch.Tensor, target: torch.Tensor, weight: torch.Tensor) -> torch.Tensor:
    """Per frame (... x 21 x 3 lifted, ... x 21 x 2 centred 2D, ... x 21 weights -> ...), the
    weighted mean distance, in body sizes, between the 2D and the lifted pose projected by the
    scale and offset that bring it nearest (weak perspective, least squares)."""
    p = projected_points(pose)[..., :2]
    q, w = target[..., SHARED_COCO, :], weight[..., SHARED_COCO]
    total = w.sum(-1, keepdim=True).clamp_min(1e-6)
    p_mean = (w[..., None] * p).sum(-2, keepdim=True) / total[..., None]
    q_mean = (w[..., None] * q).sum(-2, keepdim=True) / total[..., None]
    pc, qc = p - p_mean, q - q_mean
    spread = (w * (pc * pc).sum(-1)).sum(-1, keepdim=True).clamp_min(1e-9)
    scale = (w * (pc * qc).sum(-1)).sum(-1, keepdim=True) / spread
    residual = torch.linalg.norm(scale[..., None] * pc - qc, dim=-1)
    return (w * residual).sum(-1) / total[..., 0]


def bone_lengths(pose: torch.Tensor) -> torch.Tensor:
    """... x 21 x 3 -> ... x 22 bone lengths (body and feet)."""
    parents, children = zip(*BONES)
    return torch.linalg.norm(pose[..., list(children), :] - pose[..., list(parents), :], dim=-1)


def bone_prior(pose: torch.Tensor, capture: torch.Tensor) -> torch.Tensor:
    """VideoPose3D's bone-length term: the mean bone lengths of the video batch against the capture batch's."""
    return (bone_lengths(pose).mean(dim=tuple(range(pose.dim() - 2))) -
            bone_lengths(capture).mean(dim=tuple(range(capture.dim() - 2)))).abs().mean()


@dataclass
class AdaptResult:
    model: torch.nn.Module
    losses: dict  # name -> per-step values (capture MPJPE m, reprojection in body sizes, bone prior m)
    seconds: float


def adapt_lifter(model: torch.nn.Module, cfg: AdaptConfig, capture, video: VideoSampler | None,
                 progress: bool = True) -> AdaptResult:
    """Fine-tune ``model`` (a ``TemporalModel``, its batch norms kept as they are) for ``cfg.steps``:
    the capture's supervised loss from ``capture`` (a ``data.PairSampler``), plus, with ``video``
    and non-zero weights, the reprojection and bone-length terms on real 2D."""
    import time

    from pipeline.motion.lifting.convert import freeze_batch_norm

    torch.manual_seed(cfg.seed)
    torch.set_num_threads(max(1, cfg.threads))
    pad = model.receptive_field // 2
    chunk = capture.length - model.receptive_field + 1
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr, amsgrad=True)
    scheduler = torch.optim.lr_scheduler.ExponentialLR(optimiser, (cfg.lr_final / cfg.lr) ** (1.0 / max(1, cfg.steps)))
    semi = video is not None and (cfg.reprojection_weight or cfg.bone_weight)
    losses: dict[str, list[float]] = {"capture_mpjpe_m": [], "reprojection": [], "bone_prior_m": []}
    started = time.monotonic()
    for step in tqdm(range(cfg.steps), desc="adapt lifter", unit="step", disable=not progress):
        model.train()
        freeze_batch_norm(model)
        torch.manual_seed(cfg.seed * 1_000_003 + step)
        inputs, targets = capture.batch(cfg.batch, step)
        target = torch.from_numpy(targets[:, pad: pad + chunk])
        pred = model(torch.from_numpy(inputs))
        loss = torch.linalg.norm(pred - target, dim=-1).mean()
        losses["capture_mpjpe_m"].append(loss.item())
        if cfg.velocity_weight:
            velocity = torch.linalg.norm(torch.diff(pred, dim=1) - torch.diff(target, dim=1), dim=-1).mean()
            loss = loss + cfg.velocity_weight * velocity
        if semi:
            v_in, v_target, v_weight = video.batch(cfg.video_batch, step)
            v_pred = model(torch.from_numpy(v_in))
            reprojection = reprojection_error(v_pred, torch.from_numpy(v_target), torch.from_numpy(v_weight)).mean()
            prior = bone_prior(v_pred, target)
            loss = loss + cfg.reprojection_weight * reprojection + cfg.bone_weight * prior
            losses["reprojection"].append(reprojection.item())
            losses["bone_prior_m"].append(prior.item())
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        scheduler.step()
    model.eval()
    return AdaptResult(model, losses, time.monotonic() - started)


def video_reprojection(model: torch.nn.Module, clips: list[VideoClip]) -> dict[str, float]:
    """Per clip, the median per-frame reprojection error (body sizes) of the whole clip lifted as the
    lift stage lifts it (edge-padded, no flip): how well the 3D explains the 2D it came from."""
    from pipeline.motion.lifting.infer import Lifter

    poses = Lifter.from_torch(model, "centred").lift([c.xy for c in clips], 1, 1)  # centred: no frame size
    return {clip.name: float(reprojection_error(torch.from_numpy(pose),
                                                torch.from_numpy(normalise_centred(clip.xy, model.receptive_field)
                                                                 .astype(np.float32)),
                                                torch.from_numpy(clip.weight.astype(np.float32))).median())
            for clip, pose in zip(clips, poses)}
