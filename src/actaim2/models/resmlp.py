"""Residual MLP: the "multi-layer ResNet" of the paper's mode-selector heads (mu_c, Sigma_c, q_x, q_y)."""
from __future__ import annotations

import torch
from torch import nn


class ResidualBlock(nn.Module):
    """x + W2 act(W1 LN(x)): pre-norm keeps deep stacks trainable without tuning."""

    def __init__(self, width: int):
        super().__init__()
        self.net = nn.Sequential(nn.LayerNorm(width), nn.Linear(width, width), nn.GELU(), nn.Linear(width, width))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.net(x)


class ResMLP(nn.Module):
    """in_dim -> width -> ``blocks`` residual blocks -> out_dim."""

    def __init__(self, in_dim: int, width: int, out_dim: int, blocks: int):
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(in_dim, width),
            *[ResidualBlock(width) for _ in range(blocks)],
            nn.LayerNorm(width),
            nn.GELU(),
            nn.Linear(width, out_dim),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class GaussianHead(nn.Module):
    """ResMLP whose output is a diagonal Gaussian: (mean, log-variance), log-variance clamped for stability."""

    LOGVAR_RANGE = (-10.0, 6.0)

    def __init__(self, in_dim: int, width: int, out_dim: int, blocks: int, copies: int = 1):
        super().__init__()
        self.out_dim, self.copies = out_dim, copies
        self.net = ResMLP(in_dim, width, 2 * out_dim * copies, blocks)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(..., copies, out_dim) mean and log-variance (the copies axis is dropped when copies == 1)."""
        out = self.net(x).unflatten(-1, (self.copies, 2, self.out_dim))
        mean, logvar = out[..., 0, :], out[..., 1, :].clamp(*self.LOGVAR_RANGE)
        if self.copies == 1:
            return mean.squeeze(-2), logvar.squeeze(-2)
        return mean, logvar
