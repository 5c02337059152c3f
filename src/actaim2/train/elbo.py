"""Losses of the mode selectors: the CGMVAE's negative ELBO and the baselines' objectives.

CGMVAE, per sample (paper, "Mode Selector Training Loss" and appendix A), with x ~ q(x|eps,O),
y ~ q(y|eps,O) reparameterised and q(c|x,y,O) analytic:
    reconstruction  ||eps_hat - eps||^2            (the paper's L2 "in practice")
    x-prior term    sum_k q(c=k) KL(q(x|eps,O) || p(x|y,c=k,O))   (exact expectation over c)
    y-prior term    KL(q(y|eps,O) || N(0, I))
    c-prior term    KL(q(c|x,y,O) || Multi(pi))                     (exact, at most log K)
With q(c) analytic, x-prior + c-prior terms add up to -log sum_k pi_k N(x; mu_k, Sigma_k) plus
the entropy of q(x): the exact mixture prior, no relaxed draw of c needed. (A Concrete relaxation
of the c term, as the appendix's Gumbel-softmax density suggests, is unbounded as q(c) becomes
confident: measured 36 nats at initialisation against log 8 = 2.1 for the exact term, a penalty
on exactly the well-separated clusters mode discovery needs.)
One more term trains the path that sampling takes (c -> x ~ p(x|y,c,O) -> eps), which the ELBO
reaches only through the x-prior KL:
    generative      ||decoder(x_gen, O) - eps||^2, x_gen = sum_k omega_k (mu_k + sigma_k n),
                    omega ~ Gumbel-softmax(q(c|x,y,O), tau), tau annealed (models/gumbel.py)
Weights default to 1 (the paper's ELBO); the authors' code used 2 / 3 / 3 (reconstruction /
Gaussian / categorical), available through the YAML configuration.
All terms are summed over latent / embedding dimensions and averaged over the batch, so a
batch split over DDP ranks averages to the full-batch loss.
Two optional terms, not the paper's (weights 0 by default; docs/training.md, "A selector whose
clusters are all used"):
    cluster balance     log K - H(mean over the batch of q(c|x,y,O))
    cluster confidence  H(q(c|x,y,O)) per sample
And a third (weight 0 by default; docs/training.md, "Clusters that cover an object's eps"):
    cluster coverage    (1 - d) min_k ||eps_k - eps||^2 + d mean_k ||eps_k - eps||^2, eps_k cluster k's
                        draw without its noise (y = 0, x = mu_k(0, O)), d = COVERAGE_RELAXATION
The balance is a function of the whole batch: under DDP each rank takes its own share's, so the
ranks' average is not the full batch's (exact on one process, the CPU runs it was measured with).
"""
from __future__ import annotations

import math

import torch

from actaim2.models.baselines.cvae import CVAEOutput, CVAESelector
from actaim2.models.baselines.vqvae import VQVAEOutput, VQVAESelector
from actaim2.models.selector import CGMVAE, CGMVAEOutput
from actaim2.models.selector_base import ModeSelector
from actaim2.train.config import ElboWeights

# Share of the coverage term spread over all K draws, so a cluster that never wins still learns (the relaxed
# winner-takes-all of Rupprecht et al. 2017, "Learning in an uncertain world", epsilon 0.05).
COVERAGE_RELAXATION = 0.05


def gaussian_kl(mean_q: torch.Tensor, logvar_q: torch.Tensor, mean_p: torch.Tensor, logvar_p: torch.Tensor) -> torch.Tensor:
    """KL(N(mean_q, e^logvar_q) || N(mean_p, e^logvar_p)) for diagonal Gaussians, summed over the last axis."""
    return 0.5 * (logvar_p - logvar_q + (torch.exp(logvar_q) + (mean_q - mean_p) ** 2) * torch.exp(-logvar_p) - 1.0).sum(dim=-1)


def reconstruction(eps_hat: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
    """(B,) squared error summed over the embedding."""
    return ((eps_hat - eps) ** 2).sum(dim=-1)


def categorical_kl(log_q: torch.Tensor, log_p: torch.Tensor) -> torch.Tensor:
    """KL(q || p) of categorical distributions given normalised log-probabilities, summed over the last axis."""
    return (torch.exp(log_q) * (log_q - log_p)).sum(dim=-1)


def cgmvae_loss(out: CGMVAEOutput, eps: torch.Tensor, w: ElboWeights) -> tuple[torch.Tensor, dict[str, float]]:
    rec = reconstruction(out.eps, eps)
    qc = torch.exp(out.log_qc)
    kl_x = (qc * gaussian_kl(out.x_mean.unsqueeze(1), out.x_logvar.unsqueeze(1), out.prior_mean, out.prior_logvar)).sum(-1)
    kl_y = gaussian_kl(out.y_mean, out.y_logvar, torch.zeros_like(out.y_mean), torch.zeros_like(out.y_logvar))
    kl_c = categorical_kl(out.log_qc, out.log_pi)
    generative = reconstruction(out.eps_generated, eps)
    posterior = out.log_qc if out.log_qc_posterior is None else out.log_qc_posterior  # not the known clusters' one-hot
    balance = cluster_imbalance(posterior)
    doubt = -(torch.exp(posterior) * posterior).sum(dim=-1)  # H(q(c | x, y, O)) per trajectory
    coverage = cluster_coverage(out.eps_centres, eps) if out.eps_centres is not None else torch.zeros_like(rec)
    label = known_cluster_loss(out.log_qc_posterior, out.clusters) if out.clusters is not None else torch.zeros_like(rec)
    loss = (w.reconstruction * rec + w.x_prior * kl_x + w.y_prior * kl_y + w.c_prior * kl_c + w.generative * generative
            + w.cluster_confidence * doubt + w.cluster_coverage * coverage + w.known_cluster * label).mean()
    loss = loss + w.cluster_balance * balance
    return loss, {
        "reconstruction": rec.mean().item(), "kl_x": kl_x.mean().item(), "kl_y": kl_y.mean().item(),
        "kl_c": kl_c.mean().item(), "generative": generative.mean().item(), "cluster_imbalance": balance.item(),
        "cluster_entropy": doubt.mean().item(), "cluster_coverage": coverage.mean().item(), "known_cluster": label.mean().item(),
        "clusters_used": int(torch.unique(posterior.argmax(-1)).numel()),
    }


def known_cluster_loss(log_qc: torch.Tensor, clusters: torch.Tensor) -> torch.Tensor:
    """(B,) -log q(c* | x, y, O) of each row's known cluster c* (0 where it is -1, unknown).

    Why (``ElboWeights.known_cluster``): with c observed the ELBO no longer trains the posterior that
    ``assign_clusters`` reads; this is the classification term a labelled sample adds (Kingma et al. 2014, M2).
    """
    picked = log_qc.gather(1, clusters.clamp_min(0).unsqueeze(1)).squeeze(1)
    return torch.where(clusters >= 0, -picked, torch.zeros_like(picked))


def cluster_coverage(centres: torch.Tensor, eps: torch.Tensor) -> torch.Tensor:
    """(B,) relaxed winner-takes-all distance of each eps to the K clusters' noise-free draws (B, K, E) of its O_init.

    Why (``ElboWeights.cluster_coverage``): the generative term trains only the cluster q(c) picks for a
    trajectory, so for each object the clusters that receive none of its trajectories decode near the centre of
    its eps (81f01112: one object's draws lie 1.29 apart, its true eps 2.68) and the predictor, which does follow
    true eps, is served eps that name few outcomes. Scoring every trajectory against its nearest draw, as
    multiple-hypothesis prediction does (Guzman-Rivera et al. 2012), lets each cluster claim part of an object's eps.
    The hypotheses leave out the draws' noise: with it, the noise rather than the cluster decides the winner, and
    every cluster is pulled to the object's mean eps (measured: one object's draws 0.97 apart after 30 epochs).
    """
    distance = reconstruction(centres, eps.unsqueeze(1))  # (B, K)
    return (1.0 - COVERAGE_RELAXATION) * distance.min(dim=1).values + COVERAGE_RELAXATION * distance.mean(dim=1)


def cluster_imbalance(log_qc: torch.Tensor) -> torch.Tensor:
    """log K - H(the batch's mean q(c | x, y, O)): 0 when a batch spreads over the K clusters equally, log K when
    every trajectory goes to one.

    Why (``ElboWeights.cluster_balance``): nothing in the ELBO stops the posterior from putting almost every
    trajectory in one cluster (81f01112: 329 of 382), and a cluster that receives none gets little of the
    x-prior and generative gradient, so its draws decode near the centre of an object's eps and the predictor
    turns all clusters into one outcome (docs/training.md, "A selector whose clusters are all used").
    """
    mean = torch.exp(log_qc).mean(dim=0)
    return categorical_kl(torch.log(mean.clamp_min(1e-12)), torch.full_like(mean, -math.log(len(mean))))  # KL to uniform


def cvae_loss(out: CVAEOutput, eps: torch.Tensor, w: ElboWeights) -> tuple[torch.Tensor, dict[str, float]]:
    rec = reconstruction(out.eps, eps)
    kl = gaussian_kl(out.w_mean, out.w_logvar, torch.zeros_like(out.w_mean), torch.zeros_like(out.w_logvar))
    return (w.reconstruction * rec + w.x_prior * kl).mean(), {"reconstruction": rec.mean().item(), "kl_w": kl.mean().item()}


def vqvae_loss(out: VQVAEOutput, eps: torch.Tensor, w: ElboWeights, commitment: float) -> tuple[torch.Tensor, dict[str, float]]:
    rec = reconstruction(out.eps, eps)
    codebook = ((out.quantised - out.encoding.detach()) ** 2).sum(-1)
    commit = ((out.encoding - out.quantised.detach()) ** 2).sum(-1)
    prior = torch.nn.functional.cross_entropy(out.prior_logits, out.code, reduction="none")
    loss = (w.reconstruction * rec + codebook + commitment * commit + prior).mean()
    return loss, {"reconstruction": rec.mean().item(), "codebook": codebook.mean().item(),
                  "commitment": commit.mean().item(), "code_prior": prior.mean().item(),
                  "clusters_used": int(torch.unique(out.code).numel())}


def selector_loss(model: ModeSelector, views: torch.Tensor, eps: torch.Tensor, weights: ElboWeights,
                  noise: dict[str, torch.Tensor] | None = None, temperature: float = 1.0,
                  clusters: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor, dict[str, float]]:
    """(loss, reconstructed eps, metrics) of any selector on (O_init views, standardised z);
    ``temperature`` is the CGMVAE's Gumbel-softmax temperature (models/gumbel.py); ``clusters`` (B,) each
    row's known cluster, -1 where unknown (the CGMVAE's alone: ``CGMVAE.forward``).

    ``model`` may be wrapped in DistributedDataParallel; the reconstruction is returned so the
    joint phase can feed it, detached, to the action predictor without a second forward.
    """
    core = model.module if hasattr(model, "module") else model
    if isinstance(core, CGMVAE):
        out = model(views, eps, noise, temperature, cluster_centres=weights.cluster_coverage > 0, clusters=clusters)
        loss, metrics = cgmvae_loss(out, eps, weights)
        metrics["temperature"] = temperature
        return loss, out.eps, metrics
    if clusters is not None:
        raise TypeError(f"selector {type(core).__name__} takes no known clusters (the CGMVAE alone does)")
    out = model(views, eps, noise)
    if isinstance(core, CVAESelector):
        loss, metrics = cvae_loss(out, eps, weights)
    elif isinstance(core, VQVAESelector):
        loss, metrics = vqvae_loss(out, eps, weights, core.config.commitment)
    else:
        raise TypeError(f"no loss for selector {type(core).__name__}")
    return loss, out.eps, metrics
