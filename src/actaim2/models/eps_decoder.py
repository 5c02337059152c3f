"""Decoder p(eps | x, O) shared by the CGMVAE and the baselines: a small transformer over per-view tokens.

The paper's decoder (appendix, "Mode Selector Decoder Architecture") is a transformer over the
observation's per-view tokens and the latent x, "preserving the separation of multi-view
channels": the task embedding z is itself one block per camera (the image encoder E
concatenates cameras), so x is mapped to ``z_tokens`` query tokens, each reading out its block
of eps after ``layers`` self-attention layers over [view tokens, query tokens]. The output is
the mean of p(eps | x, O); its covariance is fixed (the paper trains it with an L2 loss "in
practice"), so the decoder is deterministic, as in the authors' code.
"""
from __future__ import annotations

import torch
from torch import nn


class EpsDecoder(nn.Module):
    def __init__(self, latent_dim: int, token_dim: int, z_dim: int, z_tokens: int, layers: int, heads: int):
        super().__init__()
        if z_dim % z_tokens:
            raise ValueError(f"z_dim {z_dim} is not a multiple of z_tokens {z_tokens}")
        self.z_tokens, self.token_dim = z_tokens, token_dim
        self.latent_in = nn.Linear(latent_dim, z_tokens * token_dim)
        self.query = nn.Parameter(torch.randn(z_tokens, token_dim) * 0.02)
        layer = nn.TransformerEncoderLayer(token_dim, heads, 2 * token_dim, dropout=0.0, activation="gelu",
                                           batch_first=True, norm_first=True)
        self.transformer = nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
        self.norm = nn.LayerNorm(token_dim)
        self.out = nn.Linear(token_dim, z_dim // z_tokens)

    def forward(self, latent: torch.Tensor, obs_tokens: torch.Tensor) -> torch.Tensor:
        """latent (B, latent_dim), obs_tokens (B, V, token_dim) -> eps (B, z_dim)."""
        q = self.latent_in(latent).view(-1, self.z_tokens, self.token_dim) + self.query
        h = self.transformer(torch.cat([obs_tokens, q], dim=1))[:, -self.z_tokens:]
        return self.out(self.norm(h)).flatten(1)
