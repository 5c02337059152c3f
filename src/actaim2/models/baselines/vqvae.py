"""VQVAE-RVT's mode selector: a conditional VQ-VAE with a K-entry codebook (baseline).

e = encoder(eps, O); k = nearest codebook entry; the decoder reads e_k through the
straight-through estimator (van den Oord et al. 2017), trained with the codebook and
commitment losses. Sampling needs a distribution over codes given O: a small prior head
p(k | O) is fitted by cross-entropy to the codes the encoder assigns (the role PixelCNN plays
in the original; with one discrete symbol an MLP over the view tokens is enough).
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from actaim2.models.gumbel import gumbel_max
from actaim2.models.resmlp import ResMLP
from actaim2.models.selector_base import ModeSelector, SampleResult, SelectorConfig


@dataclass
class VQVAEOutput:
    eps: torch.Tensor  # (B, eps_size) reconstruction through the straight-through code
    encoding: torch.Tensor  # (B, D) encoder output e
    quantised: torch.Tensor  # (B, D) codebook entry e_k (carries the codebook's gradient)
    code: torch.Tensor  # (B,) k
    prior_logits: torch.Tensor  # (B, K) of p(k | O)


class VQVAESelector(ModeSelector):
    def __init__(self, config: SelectorConfig):
        super().__init__(config)
        self.encoder = ResMLP(config.width, config.width, config.latent_dim, config.blocks)
        self.codebook = torch.nn.Parameter(torch.randn(config.clusters, config.latent_dim))
        self.prior = ResMLP(self.condition_dim, config.width, config.clusters, config.blocks)

    def _encode(self, flat: torch.Tensor, eps_true: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        e = self.encoder(self.joint_embedding(flat, eps_true))
        return e, torch.cdist(e, self.codebook).argmin(dim=-1)

    def draw_noise(self, batch: int, generator: torch.Generator | None = None,
                   device: torch.device | str = "cpu") -> dict[str, torch.Tensor]:
        return {}  # deterministic encoder: nothing to draw

    def forward(self, views: torch.Tensor, eps_true: torch.Tensor, noise: dict[str, torch.Tensor] | None = None) -> VQVAEOutput:
        tokens, flat = self.condition(views)
        e, k = self._encode(flat, eps_true)
        q = self.codebook[k]
        straight_through = e + (q - e).detach()
        return VQVAEOutput(self.decoder(straight_through, tokens), e, q, k, self.prior(flat))

    @torch.no_grad()
    def reconstruct(self, views: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        tokens, flat = self.condition(views)
        return self.decoder(self.codebook[self._encode(flat, eps_true)[1]], tokens)

    @torch.no_grad()
    def assign_clusters(self, views: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        return self._encode(self.condition(views)[1], eps_true)[1]

    @torch.no_grad()
    def sample(self, views: torch.Tensor, cluster: int | None = None,
               generator: torch.Generator | None = None, noise_scale: float = 1.0) -> SampleResult:
        """A code (given, or drawn from p(k | O)) decoded; ``noise_scale`` changes nothing: a code has no noise."""
        tokens, flat = self.condition(views)
        logits = self.prior(flat)
        k = self._cluster_argument(cluster, len(views), views.device)
        if k is None:
            k = gumbel_max(torch.log_softmax(logits, dim=-1), generator)
        return SampleResult(self.decoder(self.codebook[k], tokens), k, torch.softmax(logits, dim=-1))
