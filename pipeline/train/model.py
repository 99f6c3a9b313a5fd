"""A compact Two-Stream Motion Transformer (after the YouTube-Dance3D seed model).

Pose stream: every joint coordinate of a frame is discretised into ``bins`` bins and
embedded; the 51 embeddings are summed into one token per frame. Audio stream: MFCC +
deltas + beat flag per frame, projected to a token. Each stream has its own causal
transformer; their outputs are concatenated (late fusion), passed through a causal
fusion transformer, and a head predicts, for every coordinate of the *next* frame, a
``bins``-way softmax.

The seed's own layout (its Table 1 and section 3.4) is the same module with ``coord_dims`` > 0:
each coordinate's bin is embedded in ``coord_dims`` dimensions by one shared [bins, coord_dims]
matrix and the 51 embeddings are concatenated (51 x 5 = 255) and projected to the pose
width; the audio's beat flag gets a ``beat_dims`` embedding, the features pass through a causal
1D convolution with sinusoidal positions; each stream has its own width and heads; and with
``late_fusion`` the next frame's logits are W^X z^X_{t-1} + W^A z^A_t (no fusion transformer).
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
    # The seed's layout (0 / False: the compact model above).
    pose_width: int = 0         # pose stream width (0: d_model)
    audio_width: int = 0        # audio stream width (0: d_model)
    pose_heads: int = 0         # (0: heads)
    audio_heads: int = 0        # (0: heads)
    audio_ff: int = 0           # audio feed-forward width (0: ff)
    coord_dims: int = 0         # > 0: one shared [bins, coord_dims] embedding, 51 concatenated and projected
    beat_dims: int = 0          # > 0: the beat flag embedded, features through a causal 1D convolution
    late_fusion: bool = False   # logits = W^X z^X + W^A z^A instead of a fusion transformer

    @property
    def pose_d(self) -> int:
        return self.pose_width or self.d_model

    @property
    def audio_d(self) -> int:
        return self.audio_width or self.d_model

    def as_dict(self) -> dict:
        return asdict(self)


def discretise(motion: torch.Tensor, cfg: TSMTConfig) -> torch.Tensor:
    """(..., 51) metres -> (..., 51) bin indices in [0, bins)."""
    scaled = (motion + cfg.range_m) / (2 * cfg.range_m) * cfg.bins
    return scaled.floor().clamp(0, cfg.bins - 1).long()


def undiscretise(bins: torch.Tensor, cfg: TSMTConfig) -> torch.Tensor:
    return (bins.float() + 0.5) / cfg.bins * 2 * cfg.range_m - cfg.range_m


def _encoder(cfg: TSMTConfig, width: int, layers: int, heads: int = 0, ff: int = 0) -> nn.TransformerEncoder:
    layer = nn.TransformerEncoderLayer(width, heads or cfg.heads, ff or cfg.ff, cfg.dropout, batch_first=True,
                                       norm_first=True)
    return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)


def _sinusoid(frames: int, width: int) -> torch.Tensor:
    position = torch.arange(frames, dtype=torch.float32)[:, None]
    rate = torch.exp(torch.arange(0, width, 2, dtype=torch.float32) * (-torch.log(torch.tensor(1e4)) / width))
    table = torch.zeros(frames, width)
    table[:, 0::2] = torch.sin(position * rate)
    table[:, 1::2] = torch.cos(position * rate[: width // 2])
    return table


class TwoStreamMotionTransformer(nn.Module):
    def __init__(self, cfg: TSMTConfig) -> None:
        super().__init__()
        self.cfg = cfg
        pose_d, audio_d = cfg.pose_d, cfg.audio_d
        if cfg.coord_dims:
            self.coord_embedding = nn.Embedding(cfg.bins, cfg.coord_dims)   # shared by all 51 coordinates
            self.pose_in = nn.Linear(COORDS * cfg.coord_dims, pose_d)
        else:
            self.coord_embedding = nn.Embedding(COORDS * cfg.bins, pose_d)
        self.pose_position = nn.Embedding(cfg.max_frames, pose_d)
        if cfg.beat_dims:
            self.beat_embedding = nn.Embedding(2, cfg.beat_dims)
            self.audio_conv = nn.Conv1d(cfg.audio_dims - 1 + cfg.beat_dims, audio_d, 3)
            self.register_buffer("audio_sinusoid", _sinusoid(cfg.max_frames, audio_d), persistent=False)
        else:
            self.audio_in = nn.Linear(cfg.audio_dims, audio_d)
            self.audio_position = nn.Embedding(cfg.max_frames, audio_d)
        self.pose = _encoder(cfg, pose_d, cfg.pose_layers, cfg.pose_heads)
        self.audio = _encoder(cfg, audio_d, cfg.audio_layers, cfg.audio_heads, cfg.audio_ff)
        if cfg.late_fusion:
            self.pose_head = nn.Linear(pose_d, COORDS * cfg.bins)
            self.audio_head = nn.Linear(audio_d, COORDS * cfg.bins, bias=False)
        else:
            self.fusion = _encoder(cfg, pose_d + audio_d, cfg.fusion_layers)
            self.head = nn.Linear(pose_d + audio_d, COORDS * cfg.bins)
        self.register_buffer("offsets", torch.arange(COORDS) * cfg.bins, persistent=False)

    def _pose_tokens(self, pose_bins: torch.Tensor, positions: torch.Tensor) -> torch.Tensor:
        if self.cfg.coord_dims:
            b, t, _ = pose_bins.shape
            return self.pose_in(self.coord_embedding(pose_bins).reshape(b, t, -1)) + self.pose_position(positions)
        # Summing 51 embeddings: scale so the token starts at the size of one (a sane initial loss).
        return self.coord_embedding(pose_bins + self.offsets).sum(2) / COORDS ** 0.5 + self.pose_position(positions)

    def _audio_tokens(self, audio: torch.Tensor, positions: torch.Tensor) -> torch.Tensor:
        if self.cfg.beat_dims:
            beat = self.beat_embedding((audio[..., -1] > 0.5).long())
            features = torch.cat([audio[..., :-1], beat], -1).transpose(1, 2)
            causal = nn.functional.pad(features, (2, 0))  # frame t sees t-2 .. t
            return self.audio_conv(causal).transpose(1, 2) + self.audio_sinusoid[positions]
        return self.audio_in(audio) + self.audio_position(positions)

    def forward(self, pose_bins: torch.Tensor, audio: torch.Tensor) -> torch.Tensor:
        """pose_bins (B, T, 51) of frames 0..T-1, audio (B, T, A) of frames 1..T -> logits (B, T, 51, bins)
        for frames 1..T."""
        b, t, _ = pose_bins.shape
        positions = torch.arange(t, device=pose_bins.device)
        mask = nn.Transformer.generate_square_subsequent_mask(t, device=pose_bins.device)
        pose = self.pose(self._pose_tokens(pose_bins, positions), mask=mask, is_causal=True)
        music = self.audio(self._audio_tokens(audio, positions), mask=mask, is_causal=True)
        if self.cfg.late_fusion:
            logits = self.pose_head(pose) + self.audio_head(music)
        else:
            logits = self.head(self.fusion(torch.cat([pose, music], -1), mask=mask, is_causal=True))
        return logits.view(b, t, COORDS, self.cfg.bins)


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
