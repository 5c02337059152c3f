"""The mode selector P(eps | O_init): the paper's conditional Gaussian-mixture VAE (CGMVAE).

Generative model (paper, method and appendix A):
    c ~ Multi(pi)   (K clusters; pi learned; drawn with the Gumbel-max trick, gumbel.py)
    y ~ N(0, I)
    x | y, c, O ~ N(mu_c(y, O), Sigma_c(y, O))   (one ResNet-MLP gives all K components)
    eps | x, O = decoder(x, O)                    (transformer over per-view tokens, eps_decoder.py)
Inference model:
    q(x | eps, O), q(y | eps, O): ResNet-MLPs (diagonal Gaussians)
    q(c | x, y, O) = pi_c N(x; mu_c, Sigma_c) / sum_l pi_l N(x; mu_l, Sigma_l)
      computed analytically by Bayes' rule with log-sum-exp (no classifier network; the
      authors' code learns one, the paper derives it: we follow the paper).
The prior p(x | y, c, O) is conditioned on O as the paper writes (the authors' code drops O).
The loss terms live in ``actaim2.train.elbo``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from actaim2.models.gumbel import gumbel_max, gumbel_softmax, sample_gumbel
from actaim2.models.resmlp import GaussianHead
from actaim2.models.selector_base import ModeSelector, SampleResult, SelectorConfig

LOG_2PI = math.log(2.0 * math.pi)


def diagonal_gaussian_log_density(x: torch.Tensor, mean: torch.Tensor, logvar: torch.Tensor) -> torch.Tensor:
    """log N(x; mean, diag(exp(logvar))), summed over the last axis."""
    return -0.5 * (LOG_2PI + logvar + (x - mean) ** 2 * torch.exp(-logvar)).sum(dim=-1)


def cluster_log_posterior(x: torch.Tensor, prior_mean: torch.Tensor, prior_logvar: torch.Tensor,
                          log_pi: torch.Tensor) -> torch.Tensor:
    """log q(c | x, y, O) by Bayes' rule: x (B, D), prior components (B, K, D), log_pi (K,) -> (B, K).

    log q_k = log pi_k + log N(x; mu_k, Sigma_k) - logsumexp_l(log pi_l + log N(x; mu_l, Sigma_l)).
    """
    joint = torch.log_softmax(log_pi, dim=-1) + diagonal_gaussian_log_density(x.unsqueeze(-2), prior_mean, prior_logvar)
    return torch.log_softmax(joint, dim=-1)


def with_known_clusters(log_qc: torch.Tensor, clusters: torch.Tensor) -> torch.Tensor:
    """log q(c) with each row whose cluster is known (``clusters`` >= 0) set to that cluster: the ELBO of a
    labelled sample, whose c is observed (Kingma et al. 2014, M2); rows with -1 keep the posterior."""
    one_hot = torch.nn.functional.one_hot(clusters.clamp_min(0), log_qc.shape[-1]).to(log_qc.dtype)
    return torch.where((clusters >= 0).unsqueeze(-1), torch.log(one_hot.clamp_min(1e-12)), log_qc)


@dataclass
class CGMVAEOutput:
    eps: torch.Tensor  # (B, eps_size) reconstruction of the true eps
    x: torch.Tensor  # (B, Dx) sample of q(x | eps, O)
    x_mean: torch.Tensor
    x_logvar: torch.Tensor
    y_mean: torch.Tensor  # (B, Dy) of q(y | eps, O)
    y_logvar: torch.Tensor
    prior_mean: torch.Tensor  # (B, K, Dx) mu_c(y, O) at the sampled y
    prior_logvar: torch.Tensor
    log_pi: torch.Tensor  # (K,) normalised
    log_qc: torch.Tensor  # (B, K) log q(c | x, y, O), one-hot on the rows given a known cluster
    eps_generated: torch.Tensor  # (B, eps_size) decoded along the sampling path, c relaxed (Gumbel-softmax)
    eps_centres: torch.Tensor | None = None  # (B, K, eps_size) each cluster's noise-free draw (y = 0, x = mu_k); when asked
    # (B, K) the analytic log q(c | x, y, O) and (B,) each row's known cluster (-1: unknown), when clusters were given
    log_qc_posterior: torch.Tensor | None = None
    clusters: torch.Tensor | None = None


class CGMVAE(ModeSelector):
    def __init__(self, config: SelectorConfig):
        super().__init__(config)
        c, k = self.condition_dim, config.clusters
        self.q_x = GaussianHead(config.width, config.width, config.latent_dim, config.blocks)
        self.q_y = GaussianHead(config.width, config.width, config.y_dim, config.blocks)
        self.prior_x = GaussianHead(config.y_dim + c, config.width, config.latent_dim, config.blocks, copies=k)
        self.pi_logits = torch.nn.Parameter(torch.zeros(k))  # log pi up to a constant, learned

    def draw_noise(self, batch: int, generator: torch.Generator | None = None,
                   device: torch.device | str = "cpu") -> dict[str, torch.Tensor]:
        cfg = self.config
        return {
            "x": torch.randn(batch, cfg.latent_dim, generator=generator, device=device),
            "y": torch.randn(batch, cfg.y_dim, generator=generator, device=device),
            "x_prior": torch.randn(batch, cfg.latent_dim, generator=generator, device=device),
            "gumbel": sample_gumbel((batch, cfg.clusters), generator, device),
        }

    def _posteriors(self, flat: torch.Tensor, eps_true: torch.Tensor):
        """(mean, logvar) of q(x | eps, O) and of q(y | eps, O); both read [eps, O] embedded to one width."""
        h = self.joint_embedding(flat, eps_true)
        return self.q_x(h), self.q_y(h)

    def forward(self, views: torch.Tensor, eps_true: torch.Tensor, noise: dict[str, torch.Tensor] | None = None,
                temperature: float = 1.0, cluster_centres: bool = False,
                clusters: torch.Tensor | None = None) -> CGMVAEOutput:
        """Posterior path of the ELBO for a batch of (O_init views, standardised z), and the
        generative path sampling takes: c relaxed from q(c | x, y, O) at ``temperature``, x drawn
        from the relaxed mixture of p(x | y, c, O), decoded (its reconstruction trains that path).
        ``cluster_centres`` adds each cluster's draw without its noise (``eps_centres``, for the
        cluster-coverage term of train/elbo.py; K more decoder rows per sample). ``clusters`` (B,):
        each row's known cluster (a demonstration's mode label, fine-tuning), -1 where unknown; a known
        cluster replaces q(c) in the ELBO and in the generative path (:func:`with_known_clusters`)."""
        tokens, flat = self.condition(views)
        noise = noise if noise is not None else self.draw_noise(len(views), device=views.device)
        (x_mean, x_logvar), (y_mean, y_logvar) = self._posteriors(flat, eps_true)
        x = x_mean + torch.exp(0.5 * x_logvar) * noise["x"]
        y = y_mean + torch.exp(0.5 * y_logvar) * noise["y"]
        prior_mean, prior_logvar = self.prior_x(torch.cat([y, flat], dim=-1))
        log_pi = torch.log_softmax(self.pi_logits, dim=-1)
        posterior = cluster_log_posterior(x, prior_mean, prior_logvar, log_pi)
        log_qc = posterior if clusters is None else with_known_clusters(posterior, clusters)
        omega = gumbel_softmax(log_qc, temperature, noise["gumbel"]).unsqueeze(-1)  # (B, K, 1)
        components = prior_mean + torch.exp(0.5 * prior_logvar) * noise["x_prior"].unsqueeze(1)
        x_generated = (omega * components).sum(dim=1)
        # One decoder pass for both paths.
        decoded = self.decoder(torch.cat([x, x_generated]), torch.cat([tokens, tokens]))
        eps, eps_generated = decoded.split(len(x))
        return CGMVAEOutput(
            eps=eps, x=x, x_mean=x_mean, x_logvar=x_logvar, y_mean=y_mean, y_logvar=y_logvar,
            prior_mean=prior_mean, prior_logvar=prior_logvar, log_pi=log_pi, log_qc=log_qc, eps_generated=eps_generated,
            eps_centres=self.cluster_centres(tokens, flat) if cluster_centres else None,
            log_qc_posterior=None if clusters is None else posterior, clusters=clusters,
        )

    def cluster_centres(self, tokens: torch.Tensor, flat: torch.Tensor) -> torch.Tensor:
        """(B, K, eps_size): each cluster's draw of :meth:`sample` at its noise's mean (y = 0, x = mu_c(0, O)),
        decoded; differentiable. Without the noise a cluster is the same hypothesis at every step."""
        mean, _ = self.prior_x(torch.cat([flat.new_zeros(len(flat), self.config.y_dim), flat], dim=-1))  # (B, K, Dx)
        b, k = mean.shape[:2]
        return self.decoder(mean.flatten(0, 1), tokens.repeat_interleave(k, dim=0)).view(b, k, -1)

    @torch.no_grad()
    def reconstruct(self, views: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        tokens, flat = self.condition(views)
        (x_mean, _), _ = self._posteriors(flat, eps_true)
        return self.decoder(x_mean, tokens)

    @torch.no_grad()
    def cluster_probabilities(self, views: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        """(B, K) q(c | x, y, O) at the posterior means of x and y."""
        _, flat = self.condition(views)
        (x_mean, _), (y_mean, _) = self._posteriors(flat, eps_true)
        prior_mean, prior_logvar = self.prior_x(torch.cat([y_mean, flat], dim=-1))
        return torch.exp(cluster_log_posterior(x_mean, prior_mean, prior_logvar, self.pi_logits))

    @torch.no_grad()
    def assign_clusters(self, views: torch.Tensor, eps_true: torch.Tensor) -> torch.Tensor:
        """argmax q(c | x, y, O) at the posterior means of x and y."""
        return self.cluster_probabilities(views, eps_true).argmax(dim=-1)

    @torch.no_grad()
    def sample(self, views: torch.Tensor, cluster: int | None = None,
               generator: torch.Generator | None = None, noise_scale: float = 1.0) -> SampleResult:
        """c (given, or Gumbel-max from pi) -> y ~ N(0, s^2 I) -> x ~ N(mu_c(y, O), s^2 Sigma_c(y, O)) -> eps = decoder(x, O),
        s = ``noise_scale`` (1: the generative model; 0: x = mu_c(0, O), the noise-free draw ``cluster_centres`` gives)."""
        tokens, flat = self.condition(views)
        b, dev = len(views), views.device
        probs = torch.softmax(self.pi_logits, dim=-1).expand(b, -1)
        c = self._cluster_argument(cluster, b, dev)
        if c is None:
            c = gumbel_max(torch.log(probs), generator)
        y = noise_scale * torch.randn(b, self.config.y_dim, generator=generator, device=dev)
        prior_mean, prior_logvar = self.prior_x(torch.cat([y, flat], dim=-1))
        rows = torch.arange(b, device=dev)
        mean, logvar = prior_mean[rows, c], prior_logvar[rows, c]
        x = mean + noise_scale * torch.exp(0.5 * logvar) * torch.randn(mean.shape, generator=generator, device=dev)
        return SampleResult(self.decoder(x, tokens), c, probs)
