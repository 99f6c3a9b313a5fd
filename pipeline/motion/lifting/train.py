"""Training the lifter on motion capture, evaluating it on held-out sequences, exporting ONNX.

Training survives a stopped session: a checkpoint (weights, optimiser, scheduler, losses) is
written every few minutes, and a run started again with the same config, data and code resumes
from it. Every step's randomness (its windows, augmentation and dropout) is seeded by the step
number, so a resumed run gives the same bytes as one that was never stopped.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
from tqdm import tqdm

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
    # source -> factor on its frames' share of the windows drawn (1 where unnamed): everyday motion
    # must not drown the dance (docs/pipeline/3d.md)
    source_weights: dict = field(default_factory=dict)
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


def checkpoint_path(folder: Path, cfg: LifterConfig, train: list[MocapSequence]) -> Path:
    """Where a run keeps its checkpoint: named by what makes the model (config, training
    sequences, the training code), so a changed run never resumes another's."""
    import sys

    from pipeline.core.storage import code_fingerprint
    from pipeline.motion.lifting import data, geometry, model
    from pipeline.motion.mocap import bvh, markers, skeleton, sources

    code = code_fingerprint(model, data, geometry, sys.modules[__name__], sources, markers, bvh, skeleton)
    key = json.dumps({"cfg": asdict(cfg), "train": [(s.name, s.frames) for s in train], "code": code},
                     sort_keys=True, default=str)
    return Path(folder) / f"lifter-{hashlib.sha256(key.encode()).hexdigest()[:16]}.pt"


def default_checkpoints() -> Path:
    """``$DANCE3D_CHECKPOINTS``, else ``~/.cache/dance3d/checkpoints`` (outside any work tree)."""
    configured = os.environ.get("DANCE3D_CHECKPOINTS")
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return Path(configured) if configured else cache / "dance3d" / "checkpoints"


def _save_checkpoint(path: Path, step: int, model, optimiser, scheduler, losses: list[float], elapsed: float) -> None:
    from pipeline.core.storage import atomic_path

    with atomic_path(path) as tmp:
        torch.save({"step": step, "model": model.state_dict(), "optimiser": optimiser.state_dict(),
                    "scheduler": scheduler.state_dict(), "losses": losses, "elapsed": elapsed}, tmp)


def _step_seed(seed: int, step: int) -> int:
    return (seed * 1_000_003 + step + 1) % (2 ** 63)


def train_lifter(cfg: LifterConfig, train: list[MocapSequence], val: list[MocapSequence], *,
                 checkpoint: Path | None = None, checkpoint_minutes: float = 5.0, progress: bool = True,
                 stop_after: int | None = None, evaluate_after: bool = True) -> TrainResult:
    """Train, resuming from ``checkpoint`` when it exists and saving to it every
    ``checkpoint_minutes`` and at the end. ``stop_after``: stop (with a checkpoint) once this many
    steps are done, as a stopped session would (tests, benchmarks)."""
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(max(1, cfg.threads))
    joints = 21 if cfg.feet else 17
    model = TemporalModel(joints, joints, cfg.filter_widths, cfg.channels, cfg.dropout)
    rf = model.receptive_field
    pad = rf // 2
    length = rf + cfg.chunk - 1
    sampler = PairSampler(train, length, cfg.augment, cfg.seed, cfg.input_norm, rf, cfg.feet, cfg.source_weights)
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr, amsgrad=True)
    gamma = (cfg.lr_final / cfg.lr) ** (1.0 / max(1, cfg.steps))
    scheduler = torch.optim.lr_scheduler.ExponentialLR(optimiser, gamma)
    losses: list[float] = []
    first, elapsed = 0, 0.0
    if checkpoint is not None and Path(checkpoint).is_file():
        state = torch.load(checkpoint, weights_only=False)
        model.load_state_dict(state["model"])
        optimiser.load_state_dict(state["optimiser"])
        scheduler.load_state_dict(state["scheduler"])
        first, losses, elapsed = state["step"], list(state["losses"]), state["elapsed"]
        log.info("resuming from %s at step %d of %d", checkpoint, first, cfg.steps)
    started = time.monotonic() - elapsed
    saved = time.monotonic()
    last = min(cfg.steps, stop_after) if stop_after is not None else cfg.steps
    bar = tqdm(total=cfg.steps, initial=first, desc="train_lifter", unit="step", disable=not progress)
    for step in range(first, last):
        model.train()
        torch.manual_seed(_step_seed(cfg.seed, step))  # dropout: by step, as the data
        # BatchNorm momentum decays from 0.1 to 0.001, as in VideoPose3D's training.
        model.set_bn_momentum(0.1 * 0.01 ** (step / max(1, cfg.steps - 1)))
        inputs, targets = sampler.batch(cfg.batch, step)
        target = torch.from_numpy(targets[:, pad: pad + cfg.chunk])
        pred = model(torch.from_numpy(inputs))
        loss = _loss(pred, target, cfg)
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        scheduler.step()
        losses.append(torch.linalg.norm(pred.detach() - target, dim=-1).mean().item())
        bar.update(1)
        if step % 50 == 0:
            bar.set_postfix(mpjpe_mm=f"{1000 * sum(losses[-50:]) / len(losses[-50:]):.1f}")
        if checkpoint is not None and time.monotonic() - saved > checkpoint_minutes * 60:
            _save_checkpoint(checkpoint, step + 1, model, optimiser, scheduler, losses, time.monotonic() - started)
            saved = time.monotonic()
        if cfg.max_minutes and time.monotonic() - started > cfg.max_minutes * 60:
            log.info("time budget reached after %d steps", step + 1)
            break
    bar.close()
    train_seconds = time.monotonic() - started
    if checkpoint is not None and len(losses) > first:
        _save_checkpoint(checkpoint, len(losses), model, optimiser, scheduler, losses, train_seconds)
    metrics = evaluate(model, val, cfg) if evaluate_after else {}
    metrics.update({"steps": len(losses), "receptive_field": rf, "channels": cfg.channels,
                    "filter_widths": list(cfg.filter_widths), "train_sequences": len(train),
                    "val_sequences": len(val), "train_minutes": round(sum(s.frames / s.fps for s in train) / 60, 2),
                    "train_seconds": round(train_seconds, 1),
                    "source_share": {k: round(v, 3) for k, v in sorted(sampler.share().items())}})
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
