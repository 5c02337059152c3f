"""Mode selector internals: the analytic cluster posterior, the Gumbel-max draw, the sampling API."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.special import logsumexp, softmax
from scipy.stats import chisquare, multivariate_normal

from actaim2.models.gumbel import gumbel_max, gumbel_softmax, gumbel_temperature, sample_gumbel
from actaim2.models.obs_encoder import ObsEncoderConfig
from actaim2.models.registry import build_selector
from actaim2.models.selector import cluster_log_posterior
from actaim2.models.selector_base import SelectorConfig

SMALL = dict(z_dim=12, z_tokens=3, width=32, blocks=1, decoder_layers=1, decoder_heads=2, latent_dim=6, y_dim=4,
             obs=ObsEncoderConfig(input_resolution=16, widths=(8, 16), token_dim=16))


def bayes_reference(x: np.ndarray, means: np.ndarray, variances: np.ndarray, pi: np.ndarray) -> np.ndarray:
    """q(c | x) = pi_c N(x; mu_c, diag var_c) / sum_l ..., by scipy, one sample at a time."""
    out = np.zeros((len(x), len(pi)))
    for b in range(len(x)):
        log_joint = np.array([np.log(pi[k]) + multivariate_normal(means[b, k], np.diag(variances[b, k])).logpdf(x[b])
                              for k in range(len(pi))])
        out[b] = np.exp(log_joint - logsumexp(log_joint))
    return out


def test_cluster_posterior_matches_bayes_and_sums_to_one():
    rng = np.random.default_rng(0)
    b, k, d = 16, 8, 5
    x = rng.normal(size=(b, d))
    means = rng.normal(size=(b, k, d)) * 0.7
    variances = np.exp(rng.normal(size=(b, k, d)) * 0.5)
    pi = softmax(rng.normal(size=k))
    got = torch.exp(cluster_log_posterior(torch.from_numpy(x), torch.from_numpy(means),
                                          torch.log(torch.from_numpy(variances)), torch.log(torch.from_numpy(pi)))).numpy()
    np.testing.assert_allclose(got, bayes_reference(x, means, variances, pi), atol=1e-6, rtol=0)
    np.testing.assert_allclose(got.sum(axis=1), 1.0, atol=1e-12)
    assert got.std() > 0.05  # the case is not degenerate: posteriors differ across clusters


def test_cluster_posterior_is_one_hot_on_separated_components_and_prior_when_they_coincide():
    k, d = 8, 4
    means = torch.arange(k, dtype=torch.float64)[:, None].repeat(1, d) * 20.0  # components 40 sigma apart
    logvar = torch.zeros(k, d, dtype=torch.float64)
    log_pi = torch.log(torch.tensor(softmax(np.linspace(-1, 1, k))))
    x = means[[2, 5, 7]] + 0.1
    q = torch.exp(cluster_log_posterior(x, means.expand(3, -1, -1), logvar.expand(3, -1, -1), log_pi))
    np.testing.assert_allclose(q.numpy(), np.eye(k)[[2, 5, 7]], atol=1e-9)
    same = torch.zeros(3, k, d, dtype=torch.float64)
    q = torch.exp(cluster_log_posterior(torch.randn(3, d, dtype=torch.float64), same, same, log_pi))
    np.testing.assert_allclose(q.numpy(), np.exp(log_pi.numpy())[None].repeat(3, 0), atol=1e-12)


def test_gumbel_max_draws_follow_softmax_of_logits():
    logits = torch.tensor([1.5, 0.2, -0.7, 0.0, 2.1, -2.0, 0.9, 0.4])
    draws = gumbel_max(logits.expand(100_000, -1), torch.Generator().manual_seed(0))
    counts = np.bincount(draws.numpy(), minlength=len(logits))
    expected = softmax(logits.double().numpy()) * len(draws)
    assert chisquare(counts, expected).pvalue > 0.001


def test_gumbel_softmax_argmax_follows_softmax_and_hardens_as_the_temperature_falls():
    logits = torch.tensor([1.5, 0.2, -0.7, 0.0, 2.0, -2.0, 0.5, 1.0])
    noise = sample_gumbel((100_000, 8), torch.Generator().manual_seed(3))
    for tau in (1.0, 0.5):
        omega = gumbel_softmax(torch.log_softmax(logits, -1), tau, noise)
        assert torch.allclose(omega.sum(-1), torch.ones(len(omega)), atol=1e-5)
        counts = np.bincount(omega.argmax(-1).numpy(), minlength=8)
        assert chisquare(counts, 100_000 * softmax(logits.double().numpy())).pvalue > 0.001
    hard = lambda tau: gumbel_softmax(torch.log_softmax(logits, -1), tau, noise).max(-1).values.mean().item()  # noqa: E731
    assert hard(0.1) > hard(0.5) > hard(1.0) > hard(5.0)
    assert hard(0.01) > 0.99


def test_temperature_schedule_holds_at_its_end_points():
    assert gumbel_temperature(0.0) == 1.0
    assert gumbel_temperature(10.0) == pytest.approx(np.exp(-0.139))
    crossing = np.log(2.0) / 0.0139  # exp(-0.0139 epoch) = 0.5 at ~49.9 epochs
    assert gumbel_temperature(crossing - 1.0) > 0.5
    assert gumbel_temperature(crossing + 1.0) == 0.5 == gumbel_temperature(10_000.0)
    temps = [gumbel_temperature(e) for e in range(0, 200)]
    assert all(a >= b for a, b in zip(temps, temps[1:]))


@pytest.mark.parametrize("kind", ["cgmvae", "cvae", "vqvae"])
def test_sampling_interface(kind):
    torch.manual_seed(0)
    model = build_selector(SelectorConfig(kind=kind, **SMALL)).eval()
    views = torch.rand(3, 5, 8, 16, 16)
    a = model.sample(views, None, torch.Generator().manual_seed(3))
    b = model.sample(views, None, torch.Generator().manual_seed(3))
    assert a.eps.shape == (3, 12) and torch.equal(a.eps, b.eps) and torch.equal(a.cluster, b.cluster)
    if kind == "cvae":
        assert (a.cluster == -1).all() and a.cluster_probabilities.shape == (3, 0)
        with pytest.raises(ValueError, match="no clusters"):
            model.sample(views, 2)
        return
    assert a.cluster_probabilities.shape == (3, 8)
    torch.testing.assert_close(a.cluster_probabilities.sum(-1), torch.ones(3))
    chosen = model.sample(views, 5, torch.Generator().manual_seed(3))
    assert (chosen.cluster == 5).all()
    other = model.sample(views, 6, torch.Generator().manual_seed(3))
    assert not torch.allclose(chosen.eps, other.eps)  # the cluster changes eps
    with pytest.raises(ValueError, match="cluster must be in 0..7"):
        model.sample(views, 8)


@pytest.mark.parametrize("kind", ["cgmvae", "cvae", "vqvae"])
def test_noise_scale_zero_gives_one_eps_per_cluster_and_views_and_one_keeps_the_draws(kind):
    torch.manual_seed(0)
    model = build_selector(SelectorConfig(kind=kind, **SMALL)).eval()
    views = torch.rand(2, 5, 8, 16, 16)
    cluster = None if kind == "cvae" else 3

    def draw(seed: int, scale: float) -> torch.Tensor:
        return model.sample(views, cluster, torch.Generator().manual_seed(seed), noise_scale=scale).eps

    assert torch.equal(draw(1, 0.0), draw(2, 0.0))
    default = model.sample(views, cluster, torch.Generator().manual_seed(1)).eps
    assert torch.equal(draw(1, 1.0), default)
    if kind == "vqvae":  # a code decodes to one eps whatever the scale
        assert torch.equal(draw(1, 0.0), default)
        return
    assert not torch.allclose(draw(1, 1.0), draw(2, 1.0))
    assert not torch.allclose(draw(1, 0.5), default)
    if kind == "cgmvae":  # scale 0 is the cluster's noise-free draw the coverage term trains (CGMVAE.cluster_centres)
        with torch.no_grad():
            tokens, flat = model.condition(views)
            torch.testing.assert_close(draw(1, 0.0), model.cluster_centres(tokens, flat)[:, 3])


def test_z_standardisation_does_not_blow_up_dimensions_constant_in_training():
    """A dead encoder feature (constant on the training set) stays bounded when an unseen object moves it."""
    torch.manual_seed(0)
    model = build_selector(SelectorConfig(kind="cgmvae", **SMALL))
    z = torch.randn(64, 12) * torch.linspace(0.5, 2.0, 12)
    z[:, 0] = 0.25  # constant in training
    model.fit_statistics(torch.rand(64, 5, 8, 16, 16), z)
    spread = z.std(dim=0)
    torch.testing.assert_close(model.z_std[6:], spread[6:])  # above the median: standardised as usual
    unseen = torch.zeros(1, 12)
    unseen[0, 0] = 1.25  # the dead feature moves by 1.0 on an unseen object
    assert 0.0 < model.standardise(unseen)[0, 0] <= 1.0 / float(spread.median()) + 1e-4  # was 1e6 with a 1e-6 floor


@pytest.mark.parametrize("kind", ["cgmvae", "cvae", "vqvae"])
def test_eps_as_principal_components_is_whitened_on_training_z_and_survives_a_checkpoint(kind, tmp_path):
    """eps_dim > 0: eps = the first principal components of standardised z, unit variance and uncorrelated on the
    training set, the leading one along z's main direction of variation; the basis is saved with the weights."""
    from actaim2.artifact.checkpoint import load_policy, policy_tensors, save

    torch.manual_seed(0)
    config = SelectorConfig(kind=kind, **{**SMALL, "eps_dim": 3})
    model = build_selector(config)
    direction = torch.nn.functional.normalize(torch.randn(12), dim=0)
    t = torch.randn(200)
    z = torch.randn(200, 12) * 0.1 + t[:, None] * 3.0 * direction  # one strong direction of variation, t along it
    model.fit_statistics(torch.rand(200, 5, 8, 16, 16), z)
    eps = model.standardise(z)
    assert eps.shape == (200, 3)
    torch.testing.assert_close(torch.cov(eps.T), torch.eye(3), atol=1e-3, rtol=0)
    assert abs(float(torch.corrcoef(torch.stack([eps[:, 0], t]))[0, 1])) > 0.99
    sample = model.eval().sample(torch.rand(2, 5, 8, 16, 16), None, torch.Generator().manual_seed(1))
    assert sample.eps.shape == (2, 3)

    save(tmp_path / "policy", policy_tensors(model, None), {"selector_config": config.to_dict()})
    loaded = load_policy(tmp_path / "policy").selector
    torch.testing.assert_close(loaded.standardise(z), eps)


def test_eps_dim_needs_more_training_trajectories_than_components():
    model = build_selector(SelectorConfig(kind="cgmvae", **{**SMALL, "eps_dim": 3}))
    with pytest.raises(ValueError, match="more than 3 training trajectories"):
        model.fit_statistics(torch.rand(3, 5, 8, 16, 16), torch.randn(3, 12))
    with pytest.raises(ValueError, match="not a multiple of z_tokens"):
        SelectorConfig(kind="cgmvae", **{**SMALL, "eps_dim": 4})
