"""ActAIM's mode selector: a conditional VAE with one continuous Gaussian latent (baseline).

q(w | eps, O) diagonal Gaussian, prior N(0, I), decoder p(eps | w, O) the same transformer as
the CGMVAE's. It has no discrete modes: ``sample`` refuses a cluster and reports cluster -1.
"""
from __future__ import annotations

from dataclasses import dataclass

import torch

from actaim2.models.resmlp import GaussianHead
from actaim2.models.selector_base import ModeSelector, SampleResult, SelectorConfig


@dataclass
class CVAEOutput:
    eps: torch.Tensor  # (B, eps_size) reconstruction
    w_mean: torch.Tensor  # (B, latent_dim) of q(w | eps, O)
    w_logvar: torch.Tensor


class CVAESelector(ModeSelector):
    def __init__(self, config: SelectorConfig):
        super().__init__(config)
        self.q_w = GaussianHead(config.width, config.width, config.latent_dim, config.blocks)

    def _posterior(self, flat: torch.Tensor, eps_true: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.q_w(self.joint_embedding(flat, eps_true))

    def draw_noise(self, batch: int, generator: torch.Generator | None = None,
                   device: torch.device | str = "cpu") -> dict[str, torch.Tensor]:
        return {"w": torch.randn(batch, self.config.latent_dim, generator=generator, device=device)}

    def forward(self, views: torch.Tensor, eps_true: torch.Tensor, noise: dict[str, torch.Tensor] | None = None) -> CVAEOutput:
        tokens, flat = self.condition(views)
        noise = noise if noise is not None else self.draw_noise(len(views), device=views.device)
        mean, logvar = self._posterior(flat, eps_true)
        w = mean + torch.exp(0.5 * logvar) * noise["w"]
        return CVAEOutput(self.decoder(w, tokens), mean, logvar)

    @torch.no_grad()
    def reconstruct(self, views: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        tokens, flat = self.condition(views)
        return self.decoder(self._posterior(flat, eps_true)[0], tokens)

    @torch.no_grad()
    def assign_clusters(self, views: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        return torch.full((len(views),), -1, dtype=torch.long, device=views.device)

    @torch.no_grad()
    def sample(self, views: torch.Tensor, cluster: int | None = None,
               generator: torch.Generator | None = None, noise_scale: float = 1.0) -> SampleResult:
        if cluster is not None:
            raise ValueError("the CVAE selector has no clusters: call sample with cluster=None")
        tokens, _ = self.condition(views)
        b = len(views)
        w = noise_scale * torch.randn(b, self.config.latent_dim, generator=generator, device=views.device)
        return SampleResult(self.decoder(w, tokens), torch.full((b,), -1, dtype=torch.long, device=views.device),
                            torch.zeros(b, 0, device=views.device))
