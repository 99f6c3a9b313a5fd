"""Training the contact model on motion capture, its held-out protocol, and its ONNX export.

Training windows are motion capture filmed by the lifter's random virtual cameras, with the
lifter's 2D augmentations (jitter, pose-model noise, missing joints, left/right swaps), so the
model meets the 2D it will get; labels are the capture's own planted heels and toe tips
(``contact.capture_contact``) in the same, possibly sped-up and mirrored, window. A share of
windows has the heels and toes standing at the ankles, as the lift stage feeds a pose model
without feet, so the model also works from the ankles alone. The 2D is not denoised as the lift
stage denoises it: trained so, the model scored lower on the denoised 2D it gets than the model
trained on the raw noise (docs/reports/world.md, 2026-12-06).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import nn

from pipeline.motion.lifting.data import AugmentOptions, film
from pipeline.motion.lifting.evaluate import HOLDOUT, PROTOCOL_CAMERAS, add_pose_noise, view
from pipeline.motion.lifting.infer import denoise_2d
from pipeline.motion.mocap.skeleton import FEET_ANKLES_COCO
from pipeline.motion.mocap.sources import MocapSequence, first_seconds, resample
from pipeline.motion.world.contact import capture_contact, standing_level
from pipeline.motion.world.contact_model import FPS, HALF, ContactModel, features

log = logging.getLogger(__name__)
POINTS = ("left_heel", "right_heel", "left_toe", "right_toe")


class ContactNet(nn.Module):
    """(N, 2 HALF + 1, 21, 2) normalised keypoints -> (N, 4) logits of the centre frame's planted points."""

    def __init__(self, hidden: int = 256, dropout: float = 0.1) -> None:
        super().__init__()
        self.net = nn.Sequential(nn.Flatten(), nn.Linear((2 * HALF + 1) * 21 * 2, hidden), nn.ReLU(),
                                 nn.Dropout(dropout), nn.Linear(hidden, hidden), nn.ReLU(), nn.Dropout(dropout),
                                 nn.Linear(hidden, 4))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


@dataclass(frozen=True)
class ContactConfig:
    hidden: int = 256
    dropout: float = 0.1
    steps: int = 3000
    batch: int = 64          # filmed windows per step
    chunk: int = 16          # scored frames per window
    lr: float = 1e-3
    lr_final: float = 1e-4
    seed: int = 0
    threads: int = 2
    no_feet: float = 0.1     # share of windows whose heels and toes stand at the ankles (a pose model without feet)
    holdout: tuple[str, ...] = HOLDOUT
    eval_seconds: float = 60.0
    augment: AugmentOptions = field(default_factory=lambda: AugmentOptions(pose_noise=(0.0, 0.6)))


def without_feet(xy: np.ndarray) -> np.ndarray:
    """Keypoints (… x 21 x 2) with each heel and toe tip at its ankle (what the lift stage feeds
    from a pose model without feet)."""
    xy = xy.copy()
    xy[..., 17:, :] = xy[..., list(FEET_ANKLES_COCO), :]
    return xy


class ContactSampler:
    """Random training windows (features, labels), sequences drawn in proportion to their length."""

    def __init__(self, sequences: list[MocapSequence], cfg: ContactConfig) -> None:
        self.sequences = [s for s in sequences if s.frames >= 2 and s.feet is not None]
        self.levels = [standing_level(s.feet, s.fps) for s in self.sequences]
        weights = np.array([s.frames for s in self.sequences], float)
        self.p = weights / weights.sum()
        self.cfg = cfg
        self.rng = np.random.default_rng(cfg.seed)

    def batch(self) -> tuple[np.ndarray, np.ndarray]:
        cfg, length = self.cfg, 2 * HALF + self.cfg.chunk
        centres = np.arange(HALF, HALF + cfg.chunk)
        inputs, labels = [], []
        for i in self.rng.choice(len(self.sequences), size=cfg.batch, p=self.p):
            shot = film(self.sequences[i], length, self.rng, cfg.augment, feet=True)
            level = (self.levels[i] - shot.centre[1]) * shot.scale + shot.centre[1]
            xy = without_feet(shot.xy) if self.rng.random() < cfg.no_feet else shot.xy
            inputs.append(features(xy, centres))
            labels.append(capture_contact(shot.world[:, 17:], FPS, level)[centres])
        return np.concatenate(inputs), np.concatenate(labels).astype(np.float32)


@dataclass
class ContactResult:
    model: ContactNet
    metrics: dict
    losses: list[float]


def train_contact(cfg: ContactConfig, train: list[MocapSequence], val: list[MocapSequence]) -> ContactResult:
    """Sequences at ``FPS`` (``resample``)."""
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(max(1, cfg.threads))
    model = ContactNet(cfg.hidden, cfg.dropout)
    sampler = ContactSampler(train, cfg)
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    scheduler = torch.optim.lr_scheduler.ExponentialLR(optimiser, (cfg.lr_final / cfg.lr) ** (1 / max(1, cfg.steps)))
    loss_fn = nn.BCEWithLogitsLoss()
    losses: list[float] = []
    started = time.monotonic()
    for step in range(cfg.steps):
        model.train()
        x, y = sampler.batch()
        loss = loss_fn(model(torch.from_numpy(x)), torch.from_numpy(y))
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        scheduler.step()
        losses.append(loss.item())
        if step % 500 == 0:
            log.info("step %d/%d: training loss %.3f", step, cfg.steps, losses[-1])
    metrics = evaluate_contact(ContactModel.from_torch(model), val, cfg.eval_seconds, cfg.seed + 1)
    metrics.update({"steps": len(losses), "train_seconds": round(time.monotonic() - started, 1),
                    "train_sequences": len(train), "val_sequences": len(val),
                    "train_minutes": round(sum(s.frames for s in train) / FPS / 60, 2)})
    return ContactResult(model, metrics, losses)


def f1(estimate: np.ndarray, truth: np.ndarray) -> float:
    hits = float((estimate & truth).sum())
    return 2 * hits / max(1.0, float(estimate.sum() + truth.sum()))


def evaluate_contact(model: ContactModel, val: list[MocapSequence], max_seconds: float = 60.0,
                     seed: int = 1, denoise: float = 0.0) -> dict:
    """The held-out protocol: every held-out sequence through the lifter protocol's ten cameras,
    noisy 2D (expected OKS 0.80; with ``denoise``, denoised as the lift stage does), contact F1 of each
    point at probability 0.5 against the capture's labels, pooled per source and over all; beside it,
    the F1 of calling every frame planted (the baseline an F1 must beat)."""
    rng = np.random.default_rng(seed)
    pooled: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for seq in val:
        seq = first_seconds(resample(seq, FPS), max_seconds)
        if seq.feet is None or seq.frames < 2:
            continue
        truth = capture_contact(seq.feet, FPS)
        for camera in PROTOCOL_CAMERAS:
            xy, _ = view(np.concatenate([seq.h36m, seq.feet], 1), np.concatenate([seq.coco, seq.feet], 1), camera)
            prob = model.probabilities(denoise_2d(add_pose_noise(xy, rng), FPS, denoise), FPS)
            pooled.setdefault(seq.source, []).append((prob > 0.5, truth))

    def scores(pairs: list[tuple[np.ndarray, np.ndarray]]) -> dict:
        est = np.concatenate([p for p, _ in pairs])
        truth = np.concatenate([t for _, t in pairs])
        row = {f"f1_{name}": round(f1(est[:, k], truth[:, k]), 4) for k, name in enumerate(POINTS)}
        row["f1"] = round(f1(est, truth), 4)
        row["f1_all_planted"] = round(f1(np.ones_like(truth), truth), 4)
        row["true_share"] = round(float(truth.mean()), 4)
        return row

    per_source = {source: scores(pairs) for source, pairs in pooled.items()}
    every = [pair for pairs in pooled.values() for pair in pairs]
    return {"contact_f1": scores(every)["f1"] if every else float("nan"),
            "heldout": {"all": scores(every) if every else {}, **per_source}}


def export_onnx(model: ContactNet, path: Path, extra: dict | None = None) -> None:
    """ONNX with a dynamic batch axis; the window and rate in its metadata."""
    import onnx

    from pipeline.core.storage import atomic_path

    model.eval()
    dummy = torch.zeros(2, 2 * HALF + 1, 21, 2)
    with atomic_path(Path(path)) as tmp:
        torch.onnx.export(model, dummy, str(tmp), input_names=["keypoints2d"], output_names=["contact_logits"],
                          dynamic_axes={"keypoints2d": {0: "batch"}, "contact_logits": {0: "batch"}},
                          opset_version=17, dynamo=False)
        proto = onnx.load(str(tmp))
        meta = {"half_window": HALF, "fps": FPS, "joints_in": "coco17+feet", "outputs": ",".join(POINTS),
                **(extra or {})}
        for key, value in meta.items():
            entry = proto.metadata_props.add()
            entry.key, entry.value = key, str(value)
        onnx.save(proto, str(tmp))


def provenance(cfg: ContactConfig, train: list[MocapSequence], val: list[MocapSequence], result: ContactResult,
               mocap: Path) -> dict:
    """What made a contact model, for its ONNX metadata: data, params, code, figures, the loss curve."""
    import sys

    from pipeline.core.storage import code_fingerprint
    from pipeline.motion.lifting import data, evaluate
    from pipeline.motion.mocap import markers, sources
    from pipeline.motion.shipped import training_provenance
    from pipeline.motion.world import contact, contact_model

    curve = result.losses[:: max(1, len(result.losses) // 200)]
    code = code_fingerprint(sys.modules[__name__], contact, contact_model, data, evaluate, sources, markers)
    return {**training_provenance(cfg, train, val, mocap, result.metrics, len(result.losses), code),
            "loss_curve": ",".join(f"{x:.4f}" for x in curve)}
