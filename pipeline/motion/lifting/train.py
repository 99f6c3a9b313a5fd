"""Training the lifter on motion capture, evaluating it on held-out sequences, exporting ONNX."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import torch

from pipeline.motion.lifting.data import AugmentOptions, PairSampler
from pipeline.motion.lifting.evaluate import HOLDOUT, evaluate_lifter
from pipeline.motion.lifting.infer import JOINTS_IN, JOINTS_OUT, Lifter
from pipeline.motion.lifting.model import TemporalModel
from pipeline.motion.mocap.skeleton import H36M_BONE_PAIRS, H36M_BONES
from pipeline.motion.mocap.sources import SOURCES, MocapSequence, load_source, resample

log = logging.getLogger(__name__)



@dataclass(frozen=True)
class LifterConfig:
    filter_widths: tuple[int, ...] = (3, 3, 3)   # receptive field 27 frames
    channels: int = 256
    dropout: float = 0.25
    fps: float = 25.0              # mocap is resampled to this rate before augmentation
    steps: int = 3000
    batch: int = 64
    chunk: int = 16                # output frames per training window
    lr: float = 1e-3
    lr_final: float = 1e-4         # exponential decay to this by the last step
    seed: int = 0
    max_minutes: float = 0.0       # 0: no time limit (deterministic); else stop early when reached
    threads: int = 2
    velocity_weight: float = 0.0   # weight of the velocity error (MPJVE) in the loss
    bone_weight: float = 0.0       # weight of bone-length consistency (over time, left vs right) in the loss
    input_norm: str = "centred"    # screen: VideoPose3D's; centred: about the hips, by the body's size (geometry.py)
    feet: bool = False             # also take and return the heels and toe tips (21 joints in and out)
    sources: tuple[str, ...] = SOURCES
    # Held out by performer where a source names them, else by take (see docs/pipeline/3d.md).
    holdout: tuple[str, ...] = HOLDOUT
    eval_seconds: float = 60.0     # held-out protocol: at most this much of each sequence
    augment: AugmentOptions = field(default_factory=AugmentOptions)


def load_mocap(root: Path, cfg: LifterConfig) -> list[MocapSequence]:
    sequences = []
    for source in cfg.sources:
        sequences.extend(resample(s, cfg.fps) for s in load_source(root, source))
    return sequences


@dataclass
class TrainResult:
    model: TemporalModel
    metrics: dict
    losses: list[float]


def _loss(pred: torch.Tensor, target: torch.Tensor, cfg: LifterConfig) -> torch.Tensor:
    """MPJPE, plus the velocity error and bone-length consistency when weighted."""
    loss = torch.linalg.norm(pred - target, dim=-1).mean()
    if cfg.velocity_weight:
        loss = loss + cfg.velocity_weight * torch.linalg.norm(torch.diff(pred, dim=1) - torch.diff(target, dim=1),
                                                               dim=-1).mean()
    if cfg.bone_weight:
        parents, children = zip(*H36M_BONES)
        bones = torch.linalg.norm(pred[:, :, list(children)] - pred[:, :, list(parents)], dim=-1)  # B x T x 16
        over_time = (bones - bones.mean(1, keepdim=True)).abs().mean()
        left, right = zip(*H36M_BONE_PAIRS)
        left_right = (bones[..., list(left)] - bones[..., list(right)]).abs().mean()
        loss = loss + cfg.bone_weight * (over_time + left_right)
    return loss


def train_lifter(cfg: LifterConfig, train: list[MocapSequence], val: list[MocapSequence]) -> TrainResult:
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(max(1, cfg.threads))
    joints = 21 if cfg.feet else 17
    model = TemporalModel(joints, joints, cfg.filter_widths, cfg.channels, cfg.dropout)
    rf = model.receptive_field
    pad = rf // 2
    length = rf + cfg.chunk - 1
    sampler = PairSampler(train, length, cfg.augment, cfg.seed, cfg.input_norm, rf, cfg.feet)
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr, amsgrad=True)
    gamma = (cfg.lr_final / cfg.lr) ** (1.0 / max(1, cfg.steps))
    scheduler = torch.optim.lr_scheduler.ExponentialLR(optimiser, gamma)
    losses: list[float] = []
    started = time.monotonic()
    for step in range(cfg.steps):
        model.train()
        # BatchNorm momentum decays from 0.1 to 0.001, as in VideoPose3D's training.
        model.set_bn_momentum(0.1 * 0.01 ** (step / max(1, cfg.steps - 1)))
        inputs, targets = sampler.batch(cfg.batch)
        target = torch.from_numpy(targets[:, pad: pad + cfg.chunk])
        pred = model(torch.from_numpy(inputs))
        loss = _loss(pred, target, cfg)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        scheduler.step()
        losses.append(torch.linalg.norm(pred.detach() - target, dim=-1).mean().item())
        if step % 500 == 0:
            log.info("step %d/%d: training MPJPE %.1f mm", step, cfg.steps, 1000 * losses[-1])
        if cfg.max_minutes and time.monotonic() - started > cfg.max_minutes * 60:
            log.info("time budget reached after %d steps", step + 1)
            break
    train_seconds = time.monotonic() - started
    metrics = evaluate(model, val, cfg)
    metrics.update({"steps": len(losses), "receptive_field": rf, "channels": cfg.channels,
                    "filter_widths": list(cfg.filter_widths), "train_sequences": len(train),
                    "val_sequences": len(val), "train_minutes": round(sum(s.frames for s in train) / cfg.fps / 60, 2),
                    "train_seconds": round(train_seconds, 1)})
    return TrainResult(model, metrics, losses)


def evaluate(model: TemporalModel, val: list[MocapSequence], cfg: LifterConfig) -> dict:
    """The held-out protocol (``pipeline.motion.lifting.evaluate``), lifting as the lift stage does
    (flip averaging on). Top-level keys keep the clean-2D figures for ``dvc metrics``."""
    from functools import partial

    lifter = Lifter.from_torch(model, cfg.input_norm)
    result = evaluate_lifter(partial(lifter.lift, flip=True), val, fps=cfg.fps, max_seconds=cfg.eval_seconds,
                             seed=cfg.seed + 1, feet=cfg.feet)
    clean = result["clean"]
    figures = {"val_mpjpe_mm": clean["mpjpe_mm"], "val_p_mpjpe_mm": clean["p_mpjpe_mm"],
               "mean_pose_mpjpe_mm": clean["mean_pose_mpjpe_mm"], "noisy_mpjpe_mm": result["noisy"]["mpjpe_mm"],
               "noisy_p_mpjpe_mm": result["noisy"]["p_mpjpe_mm"]}
    if cfg.feet:
        figures.update(val_feet_mpjpe_mm=clean["feet_mpjpe_mm"], noisy_feet_mpjpe_mm=result["noisy"]["feet_mpjpe_mm"],
                       mean_pose_feet_mpjpe_mm=clean["mean_pose_feet_mpjpe_mm"])
    return {**figures, "heldout": result}


def provenance(cfg: LifterConfig, train: list[MocapSequence], val: list[MocapSequence], result: TrainResult,
               mocap: Path) -> dict:
    """What made a lifter, for its ONNX metadata: data, params, code, figures, the loss curve (mm)."""
    import sys

    from pipeline.core.storage import code_fingerprint
    from pipeline.motion.lifting import data, evaluate, model
    from pipeline.motion.mocap import markers, sources
    from pipeline.motion.shipped import training_provenance

    curve = result.losses[:: max(1, len(result.losses) // 200)]
    code = code_fingerprint(model, data, sys.modules[__name__], evaluate, sources, markers)
    return {**training_provenance(cfg, train, val, mocap, result.metrics, len(result.losses), code),
            "loss_curve_mm": ",".join(f"{1000 * x:.2f}" for x in curve)}


def export_onnx(model: TemporalModel, path: Path, extra: dict | None = None, input_norm: str = "screen") -> None:
    """ONNX with dynamic batch and time axes; receptive field, input normalisation and joints in its metadata."""
    import onnx

    from pipeline.core.storage import atomic_path

    model.eval()
    dummy = torch.zeros(1, model.receptive_field + 8, model.joints_in, 2)
    with atomic_path(Path(path)) as tmp:
        torch.onnx.export(model, dummy, str(tmp), input_names=["keypoints2d"], output_names=["pose3d"],
                          dynamic_axes={"keypoints2d": {0: "batch", 1: "time"}, "pose3d": {0: "batch", 1: "time"}},
                          opset_version=17, dynamo=False)
        proto = onnx.load(str(tmp))
        meta = {"receptive_field": model.receptive_field, "filter_widths": ",".join(map(str, model.filter_widths)),
                "joints_in": JOINTS_IN[model.joints_in == 21], "joints_out": JOINTS_OUT[model.joints_out == 21],
                "units": "metres, root-relative, camera frame",
                "input_norm": input_norm,
                **(extra or {})}
        for key, value in meta.items():
            entry = proto.metadata_props.add()
            entry.key, entry.value = key, str(value)
        onnx.save(proto, str(tmp))
