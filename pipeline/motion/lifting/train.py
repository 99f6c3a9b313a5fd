"""Training the lifter on motion capture, evaluating it on held-out sequences, exporting ONNX."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from pipeline.motion.lifting.data import AugmentOptions, PairSampler, validation_set
from pipeline.motion.lifting.geometry import mpjpe, p_mpjpe
from pipeline.motion.lifting.model import TemporalModel
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
    sources: tuple[str, ...] = SOURCES
    holdout: tuple[str, ...] = ("perfume/kashiyuka", "dancedb_ucy/olivia", "cmu_subject05_iclone/005_1",
                                "tang2018_ballroom/DANCE_R_8", "bandai_namco_1/dataset-1_dance",
                                "animated_drawings_fair/8yr_old", "deepmimic/humanoid3d_dance_b")
    val_windows: int = 8           # windows per held-out sequence
    augment: AugmentOptions = field(default_factory=AugmentOptions)


def load_mocap(root: Path, cfg: LifterConfig) -> list[MocapSequence]:
    sequences = []
    for source in cfg.sources:
        sequences.extend(resample(s, cfg.fps) for s in load_source(root, source))
    return sequences


def split(sequences: list[MocapSequence], holdout: tuple[str, ...]) -> tuple[list, list]:
    """Whole sequences (by source and performer/take prefix) go to validation."""
    val = [s for s in sequences if s.name.startswith(holdout)]
    train = [s for s in sequences if not s.name.startswith(holdout)]
    return train, val


@dataclass
class TrainResult:
    model: TemporalModel
    metrics: dict
    losses: list[float]


def _mpjpe_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    return torch.linalg.norm(pred - target, dim=-1).mean()


def train_lifter(cfg: LifterConfig, train: list[MocapSequence], val: list[MocapSequence]) -> TrainResult:
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(max(1, cfg.threads))
    model = TemporalModel(17, 17, cfg.filter_widths, cfg.channels, cfg.dropout)
    rf = model.receptive_field
    pad = rf // 2
    length = rf + cfg.chunk - 1
    sampler = PairSampler(train, length, cfg.augment, cfg.seed)
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr, amsgrad=True)
    gamma = (cfg.lr_final / cfg.lr) ** (1.0 / max(1, cfg.steps))
    scheduler = torch.optim.lr_scheduler.ExponentialLR(optimiser, gamma)
    losses: list[float] = []
    started = time.monotonic()
    model.train()
    for step in range(cfg.steps):
        # BatchNorm momentum decays from 0.1 to 0.001, as in VideoPose3D's training.
        model.set_bn_momentum(0.1 * 0.01 ** (step / max(1, cfg.steps - 1)))
        inputs, targets = sampler.batch(cfg.batch)
        pred = model(torch.from_numpy(inputs))
        loss = _mpjpe_loss(pred, torch.from_numpy(targets[:, pad: pad + cfg.chunk]))
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        scheduler.step()
        losses.append(loss.item())
        if step % 500 == 0:
            log.info("step %d/%d: training MPJPE %.1f mm", step, cfg.steps, 1000 * loss.item())
        if cfg.max_minutes and time.monotonic() - started > cfg.max_minutes * 60:
            log.info("time budget reached after %d steps", step + 1)
            break
    metrics = evaluate(model, val, cfg, train)
    metrics.update({"steps": len(losses), "receptive_field": rf, "channels": cfg.channels,
                    "filter_widths": list(cfg.filter_widths), "train_sequences": len(train),
                    "val_sequences": len(val), "train_minutes": round(sum(s.frames for s in train) / cfg.fps / 60, 2),
                    "wall_seconds": round(time.monotonic() - started, 1)})
    return TrainResult(model, metrics, losses)


def evaluate(model: TemporalModel, val: list[MocapSequence], cfg: LifterConfig, train: list[MocapSequence]) -> dict:
    """Held-out MPJPE and P-MPJPE (mm), and the mean-pose baseline for scale."""
    rf = model.receptive_field
    pad = rf // 2
    length = rf + cfg.chunk - 1
    inputs, targets = validation_set(val, length, cfg.val_windows, cfg.seed + 1, cfg.augment)
    model.eval()
    with torch.no_grad():
        pred = model(torch.from_numpy(inputs)).numpy()
    target = targets[:, pad: pad + cfg.chunk]
    _, train_targets = validation_set(train, length, 2, cfg.seed + 2, cfg.augment)
    mean_pose = train_targets.reshape(-1, 17, 3).mean(0)
    return {"val_mpjpe_mm": round(1000 * mpjpe(pred, target), 2),
            "val_p_mpjpe_mm": round(1000 * p_mpjpe(pred, target), 2),
            "mean_pose_mpjpe_mm": round(1000 * mpjpe(np.broadcast_to(mean_pose, target.shape), target), 2),
            "val_windows": int(len(inputs))}


def export_onnx(model: TemporalModel, path: Path, extra: dict | None = None) -> None:
    """ONNX with dynamic batch and time axes; receptive field and joints in its metadata."""
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
                "joints_in": "coco17", "joints_out": "h36m17", "units": "metres, root-relative, camera frame",
                **(extra or {})}
        for key, value in meta.items():
            entry = proto.metadata_props.add()
            entry.key, entry.value = key, str(value)
        onnx.save(proto, str(tmp))
