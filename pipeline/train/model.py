"""A compact Two-Stream Motion Transformer (after the YouTube-Dance3D seed model).

Pose stream: every joint coordinate of a frame is discretised into ``bins`` bins and
embedded; the 51 embeddings are summed into one token per frame. Audio stream: MFCC +
deltas + beat flag per frame, projected to a token. Each stream has its own causal
transformer; their outputs are concatenated (late fusion), passed through a causal
fusion transformer, and a head predicts, for every coordinate of the *next* frame, a
``bins``-way softmax.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

COORDS = 51


@dataclass(frozen=True)
class TSMTConfig:
    bins: int = 300
    range_m: float = 1.25       # coordinates in [-range, range] m are discretised
    d_model: int = 64
    heads: int = 4
    pose_layers: int = 1
    audio_layers: int = 1
    fusion_layers: int = 1
    ff: int = 128
    dropout: float = 0.1
    audio_dims: int = 27
    max_frames: int = 480

    def as_dict(self) -> dict:
        return asdict(self)


def discretise(motion: torch.Tensor, cfg: TSMTConfig) -> torch.Tensor:
    """(..., 51) metres -> (..., 51) bin indices in [0, bins)."""
    scaled = (motion + cfg.range_m) / (2 * cfg.range_m) * cfg.bins
    return scaled.floor().clamp(0, cfg.bins - 1).long()


def undiscretise(bins: torch.Tensor, cfg: TSMTConfig) -> torch.Tensor:
    return (bins.float() + 0.5) / cfg.bins * 2 * cfg.range_m - cfg.range_m


def _encoder(cfg: TSMTConfig, width: int, layers: int) -> nn.TransformerEncoder:
    layer = nn.TransformerEncoderLayer(width, cfg.heads, cfg.ff, cfg.dropout, batch_first=True, norm_first=True)
    return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)


class TwoStreamMotionTransformer(nn.Module):
    def __init__(self, cfg: TSMTConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.coord_embedding = nn.Embedding(COORDS * cfg.bins, cfg.d_model)
        self.pose_position = nn.Embedding(cfg.max_frames, cfg.d_model)
        self.audio_in = nn.Linear(cfg.audio_dims, cfg.d_model)
        self.audio_position = nn.Embedding(cfg.max_frames, cfg.d_model)
        self.pose = _encoder(cfg, cfg.d_model, cfg.pose_layers)
        self.audio = _encoder(cfg, cfg.d_model, cfg.audio_layers)
        self.fusion = _encoder(cfg, 2 * cfg.d_model, cfg.fusion_layers)
        self.head = nn.Linear(2 * cfg.d_model, COORDS * cfg.bins)
        self.register_buffer("offsets", torch.arange(COORDS) * cfg.bins, persistent=False)

    def forward(self, pose_bins: torch.Tensor, audio: torch.Tensor) -> torch.Tensor:
        """pose_bins (B, T, 51) of frames 0..T-1, audio (B, T, A) of frames 1..T -> logits (B, T, 51, bins)
        for frames 1..T."""
        b, t, _ = pose_bins.shape
        positions = torch.arange(t, device=pose_bins.device)
        mask = nn.Transformer.generate_square_subsequent_mask(t, device=pose_bins.device)
        # Summing 51 embeddings: scale so the token starts at the size of one (a sane initial loss).
        pose = self.coord_embedding(pose_bins + self.offsets).sum(2) / COORDS ** 0.5 + self.pose_position(positions)
        music = self.audio_in(audio) + self.audio_position(positions)
        streams = [self.pose(pose, mask=mask, is_causal=True), self.audio(music, mask=mask, is_causal=True)]
        fused = torch.cat(streams, -1)
        out = self.fusion(fused, mask=mask, is_causal=True)
        return self.head(out).view(b, t, COORDS, self.cfg.bins)


def next_frame_loss(model: TwoStreamMotionTransformer, motion: torch.Tensor, audio: torch.Tensor) -> torch.Tensor:
    """Cross-entropy of predicting every next frame's 51 coordinate bins."""
    bins = discretise(motion, model.cfg)
    logits = model(bins[:, :-1], audio[:, 1:])
    return nn.functional.cross_entropy(logits.reshape(-1, model.cfg.bins), bins[:, 1:].reshape(-1))


@torch.no_grad()
def generate(model: TwoStreamMotionTransformer, seed_motion: torch.Tensor, audio: torch.Tensor, frames: int,
             temperature: float = 0.0, generator: torch.Generator | None = None) -> torch.Tensor:
    """Continue ``seed_motion`` (S, 51) for ``frames`` frames to the music ``audio`` (S + frames, A)."""
    model.eval()
    bins = discretise(seed_motion, model.cfg)[None]
    context = model.cfg.max_frames - 1
    for _ in range(frames):
        t = bins.shape[1]
        start = max(0, t - context)
        logits = model(bins[:, start:], audio[None, start + 1: t + 1])[:, -1]
        if temperature > 0:
            probs = torch.softmax(logits / temperature, -1)
            nxt = torch.multinomial(probs.reshape(-1, model.cfg.bins), 1, generator=generator).view(1, 1, -1)
        else:
            nxt = logits.argmax(-1)[:, None]
        bins = torch.cat([bins, nxt], 1)
    return undiscretise(bins[0], model.cfg)
