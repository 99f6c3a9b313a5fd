"""A compact spatio-temporal transformer lifter of the MixSTE kind (Zhang et al., CVPR 2022): each
joint of each frame is a token; blocks alternate attention across the joints of a frame (spatial)
and across the frames of a joint (temporal), and every frame of the window gets its 3D.

It takes the place of ``model.TemporalModel`` in training and lifting: input (B, T, J, 2), output
(B, T - receptive_field + 1, J, 3), the frames at least ``receptive_field // 2`` from either end.
It sees a fixed window of ``receptive_field + chunk - 1`` frames (the training window), so a longer
input is lifted in windows ``chunk`` frames apart, each giving the 3D of its middle ``chunk``
frames: the same frames the convolutions give, each from at least half the receptive field of
context on either side.
"""

from __future__ import annotations

import torch
from torch import nn


class SpatioTemporalTransformer(nn.Module):
    def __init__(self, joints_in: int = 17, joints_out: int = 17, receptive_field: int = 81, chunk: int = 16,
                 dim: int = 64, depth: int = 3, heads: int = 4, dropout: float = 0.1) -> None:
        super().__init__()
        if receptive_field % 2 == 0 or joints_in != joints_out:
            raise ValueError("the receptive field must be odd, and every joint in is a joint out")
        self.joints_in, self.joints_out = joints_in, joints_out
        self.chunk, self.window = chunk, receptive_field + chunk - 1
        self._receptive_field = receptive_field
        self.embed = nn.Linear(2, dim)
        self.joint_position = nn.Parameter(torch.zeros(1, 1, joints_in, dim))
        self.frame_position = nn.Parameter(torch.zeros(1, self.window, 1, dim))
        nn.init.trunc_normal_(self.joint_position, std=0.02)
        nn.init.trunc_normal_(self.frame_position, std=0.02)

        def block() -> nn.Module:
            return nn.TransformerEncoderLayer(dim, heads, 2 * dim, dropout, batch_first=True, norm_first=True)

        self.spatial = nn.ModuleList(block() for _ in range(depth))
        self.temporal = nn.ModuleList(block() for _ in range(depth))
        self.head = nn.Sequential(nn.LayerNorm(dim), nn.Linear(dim, 3))  # each joint's token: its 3D

    @property
    def receptive_field(self) -> int:
        return self._receptive_field

    def set_bn_momentum(self, momentum: float) -> None:
        """No batch norm here (the training loop sets it on the convolutions)."""

    def _windows(self, x: torch.Tensor) -> torch.Tensor:
        """(N, window, J, 2) -> (N, window, J_out, 3): every frame of each window."""
        n, t, j, _ = x.shape
        h = self.embed(x) + self.joint_position + self.frame_position[:, :t]
        for spatial, temporal in zip(self.spatial, self.temporal):
            h = spatial(h.reshape(n * t, j, -1)).reshape(n, t, j, -1)
            h = temporal(h.transpose(1, 2).reshape(n * j, t, -1)).reshape(n, j, t, -1).transpose(1, 2)
        return self.head(h)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, t = x.shape[0], x.shape[1]
        pad = self._receptive_field // 2
        frames = t - 2 * pad  # the output frames
        if frames < 1:
            raise ValueError(f"{t} frames in, fewer than the receptive field ({self._receptive_field})")
        starts = list(range(0, frames, self.chunk))
        need = starts[-1] + self.window
        if need > t:  # the last window runs past the input: the last frame repeated
            x = torch.cat([x, x[:, -1:].expand(b, need - t, *x.shape[2:])], dim=1)
        windows = torch.stack([x[:, s: s + self.window] for s in starts], dim=1)  # B, W, window, J, 2
        out = self._windows(windows.reshape(-1, *windows.shape[2:]))
        out = out[:, pad: pad + self.chunk].reshape(b, len(starts) * self.chunk, self.joints_out, 3)
        return out[:, :frames]
