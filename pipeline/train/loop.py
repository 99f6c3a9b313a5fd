"""Training the Two-Stream Motion Transformer on the corpus shards."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import torch
from torch.utils.data import DataLoader

from pipeline.train.dataset import WindowDataset
from pipeline.train.model import TSMTConfig, TwoStreamMotionTransformer, next_frame_loss

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TrainConfig:
    steps: int = 300
    batch: int = 8
    lr: float = 1e-4              # Adam, as the seed model
    crop_frames: int = 96         # random crop of each window per step (the whole window when 0)
    loader_workers: int = 0
    shuffle_buffer: int = 64
    seed: int = 0
    threads: int = 2
    model: TSMTConfig = field(default_factory=TSMTConfig)


def _crop(batch: dict, frames: int, generator: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    motion, audio = batch["motion"], batch["audio"]
    total = motion.shape[1]
    if frames and frames < total:
        start = int(torch.randint(0, total - frames + 1, (1,), generator=generator))
        motion, audio = motion[:, start: start + frames], audio[:, start: start + frames]
    return motion, audio


def train_tsmt(corpus: Path, cfg: TrainConfig) -> tuple[TwoStreamMotionTransformer, list[float]]:
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(max(1, cfg.threads))
    dataset = WindowDataset(Path(corpus) / "train", shuffle_buffer=cfg.shuffle_buffer, seed=cfg.seed)
    if not dataset.units:
        raise ValueError(f"no training shards in {Path(corpus) / 'train'}")
    loader = DataLoader(dataset, batch_size=cfg.batch, num_workers=cfg.loader_workers,
                        persistent_workers=cfg.loader_workers > 0)
    model = TwoStreamMotionTransformer(cfg.model)
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    generator = torch.Generator().manual_seed(cfg.seed)
    losses: list[float] = []
    epoch = 0
    model.train()
    while len(losses) < cfg.steps:
        dataset.set_epoch(epoch)
        for batch in loader:
            motion, audio = _crop(batch, cfg.crop_frames, generator)
            loss = next_frame_loss(model, motion, audio)
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            losses.append(loss.item())
            if len(losses) % 100 == 0:
                log.info("step %d/%d: loss %.3f", len(losses), cfg.steps, losses[-1])
            if len(losses) >= cfg.steps:
                break
        epoch += 1
    return model, losses


def save_model(model: TwoStreamMotionTransformer, path: Path) -> None:
    from pipeline.core.storage import atomic_path

    with atomic_path(Path(path)) as tmp:
        torch.save({"config": model.cfg.as_dict(), "state_dict": model.state_dict()}, tmp)


def load_model(path: Path) -> TwoStreamMotionTransformer:
    checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    model = TwoStreamMotionTransformer(TSMTConfig(**checkpoint["config"]))
    model.load_state_dict(checkpoint["state_dict"])
    return model.eval()
