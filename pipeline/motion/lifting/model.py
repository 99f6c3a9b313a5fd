"""The VideoPose3D temporal convolutional model (Pavllo et al., CVPR 2019), non-causal.

Parameter names and shapes follow the official ``TemporalModel`` exactly
(``expand_conv``, ``expand_bn``, ``layers_conv.{i}``, ``layers_bn.{i}``, ``shrink``), so
an official ``model_pos`` state dict loads as is.
"""

from __future__ import annotations

import torch
from torch import nn


class TemporalModel(nn.Module):
    """Input (B, T, J_in, 2) -> output (B, T - receptive_field + 1, J_out, 3)."""

    def __init__(self, joints_in: int = 17, joints_out: int = 17, filter_widths: tuple[int, ...] = (3, 3, 3),
                 channels: int = 1024, dropout: float = 0.25) -> None:
        super().__init__()
        for w in filter_widths:
            if w % 2 == 0:
                raise ValueError("filter widths must be odd")
        self.joints_in, self.joints_out = joints_in, joints_out
        self.filter_widths = tuple(filter_widths)
        self.drop = nn.Dropout(dropout)
        self.relu = nn.ReLU(inplace=True)
        self.expand_conv = nn.Conv1d(joints_in * 2, channels, filter_widths[0], bias=False)
        self.expand_bn = nn.BatchNorm1d(channels, momentum=0.1)
        layers_conv, layers_bn = [], []
        self.pad = [filter_widths[0] // 2]
        next_dilation = filter_widths[0]
        for w in filter_widths[1:]:
            self.pad.append((w - 1) * next_dilation // 2)
            layers_conv.append(nn.Conv1d(channels, channels, w, dilation=next_dilation, bias=False))
            layers_bn.append(nn.BatchNorm1d(channels, momentum=0.1))
            layers_conv.append(nn.Conv1d(channels, channels, 1, dilation=1, bias=False))
            layers_bn.append(nn.BatchNorm1d(channels, momentum=0.1))
            next_dilation *= w
        self.layers_conv = nn.ModuleList(layers_conv)
        self.layers_bn = nn.ModuleList(layers_bn)
        self.shrink = nn.Conv1d(channels, joints_out * 3, 1)

    @property
    def receptive_field(self) -> int:
        return 1 + 2 * sum(self.pad)

    def set_bn_momentum(self, momentum: float) -> None:
        self.expand_bn.momentum = momentum
        for bn in self.layers_bn:
            bn.momentum = momentum

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, t = x.shape[0], x.shape[1]
        x = x.reshape(b, t, -1).permute(0, 2, 1)
        x = self.drop(self.relu(self.expand_bn(self.expand_conv(x))))
        for i in range(len(self.pad) - 1):
            pad = self.pad[i + 1]
            res = x[:, :, pad: x.shape[2] - pad]
            x = self.drop(self.relu(self.layers_bn[2 * i](self.layers_conv[2 * i](x))))
            x = res + self.drop(self.relu(self.layers_bn[2 * i + 1](self.layers_conv[2 * i + 1](x))))
        x = self.shrink(x)
        return x.permute(0, 2, 1).reshape(b, -1, self.joints_out, 3)
