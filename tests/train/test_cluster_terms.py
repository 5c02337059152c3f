"""The CGMVAE's cluster-usage terms (ElboWeights.cluster_balance, cluster_confidence, cluster_coverage): the imbalance
is 0 for a batch spread equally over the K clusters and log K for one cluster; the coverage scores each eps against
its nearest cluster centre, a fixed hypothesis per cluster; the selector loss adds exactly the weighted terms. Known
clusters (a demonstration's mode label) replace q(c) in the ELBO and add -log q(c*) of the analytic posterior."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.models.selector import with_known_clusters
from actaim2.train.distributed import init_distributed
from actaim2.train.elbo import (
    COVERAGE_RELAXATION,
    cluster_coverage,
    cluster_imbalance,
    known_cluster_loss,
    selector_loss,
)
from actaim2.train.loop import Trainer
from synthetic import PLACEMENT, make_dataset
from test_stop_gradient import TINY


def test_the_imbalance_is_zero_for_equal_use_and_log_k_for_one_cluster():
    k = 8
    spread = torch.log(torch.eye(k).clamp_min(1e-30))  # each trajectory sure of its own cluster, all K used
    assert cluster_imbalance(spread).item() == pytest.approx(0.0, abs=1e-6)
    one = torch.log(torch.eye(k)[[3] * 5].clamp_min(1e-30))  # every trajectory in cluster 3
    assert cluster_imbalance(one).item() == pytest.approx(math.log(k), rel=1e-6)
    unsure = torch.full((5, k), -math.log(k))  # uniform q(c) everywhere: balanced, though nothing is told apart
    assert cluster_imbalance(unsure).item() == pytest.approx(0.0, abs=1e-6)


def test_the_selector_loss_adds_the_weighted_balance_and_confidence_terms(tmp_path):
    data, _ = make_dataset(6, resolution=32, seed=1)
    trainer = Trainer(TINY, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    views, z = data.selector_batch(np.arange(6))
    eps = trainer.selector.standardise(z)
    noise = trainer.selector.draw_noise(6, torch.Generator().manual_seed(7))
    plain, _, metrics = selector_loss(trainer.selector, views, eps, TINY.elbo, noise)
    weights = dataclasses.replace(TINY.elbo, cluster_balance=2.0, cluster_confidence=0.5)
    both, _, again = selector_loss(trainer.selector, views, eps, weights, noise)
    assert 0.0 <= metrics["cluster_imbalance"] <= math.log(TINY.selector.clusters)
    assert 0.0 <= metrics["cluster_entropy"] <= math.log(TINY.selector.clusters) + 1e-6
    expected = plain.item() + 2.0 * metrics["cluster_imbalance"] + 0.5 * metrics["cluster_entropy"]
    assert both.item() == pytest.approx(expected, rel=1e-5)
    assert again["cluster_imbalance"] == pytest.approx(metrics["cluster_imbalance"])


def test_the_coverage_is_the_nearest_draws_distance_relaxed_towards_the_mean():
    drawn = torch.tensor([[[0.0, 0.0], [3.0, 4.0]]])  # two clusters' draws of one sample
    at_first = cluster_coverage(drawn, torch.tensor([[0.0, 0.0]]))
    assert at_first.item() == pytest.approx(COVERAGE_RELAXATION * 25.0 / 2)  # nearest 0, the mean (0 + 25) / 2
    between = cluster_coverage(drawn, torch.tensor([[3.0, 0.0]]))  # 9 from the first, 16 from the second
    assert between.item() == pytest.approx((1 - COVERAGE_RELAXATION) * 9.0 + COVERAGE_RELAXATION * 12.5)


def test_the_coverage_centres_ignore_the_noise_and_the_loss_adds_the_weighted_term(tmp_path):
    data, _ = make_dataset(6, resolution=32, seed=1)
    trainer = Trainer(TINY, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    selector = trainer.selector.eval()
    views, z = data.selector_batch(np.arange(6))
    eps = selector.standardise(z)
    noise = selector.draw_noise(6, torch.Generator().manual_seed(7))
    centres = selector(views, eps, noise, cluster_centres=True).eps_centres
    k = TINY.selector.clusters
    assert centres.shape == (6, k, eps.shape[1]) and selector(views, eps, noise).eps_centres is None
    other = selector.draw_noise(6, torch.Generator().manual_seed(8))  # a cluster is the same hypothesis at every step
    torch.testing.assert_close(selector(views, eps, other, cluster_centres=True).eps_centres, centres)
    assert not torch.allclose(centres[:, 0], centres[:, 1])  # one hypothesis per cluster
    plain, _, metrics = selector_loss(selector, views, eps, TINY.elbo, noise)
    assert metrics["cluster_coverage"] == 0.0
    weights = dataclasses.replace(TINY.elbo, cluster_coverage=3.0)
    covered, _, again = selector_loss(selector, views, eps, weights, noise)
    assert again["cluster_coverage"] == pytest.approx(cluster_coverage(centres, eps).mean().item(), rel=1e-5)
    assert covered.item() == pytest.approx(plain.item() + 3.0 * again["cluster_coverage"], rel=1e-5)


def test_the_selector_condition_object_feeds_another_trajectorys_o_init_of_the_same_object(tmp_path):
    data, _ = make_dataset(8, resolution=32, seed=1)
    data = dataclasses.replace(data, ids=[f"box_{i % 2}-random-{i:05d}" for i in range(8)])  # two objects, rows alternate
    config = dataclasses.replace(TINY, selector_condition="object")
    trainer = Trainer(config, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    asked: list[np.ndarray] = []
    batch = trainer.train.selector_batch
    trainer.train.selector_batch = lambda rows, device="cpu": (asked.append(np.array(rows)), batch(rows, device))[1]
    rows = np.arange(len(trainer.train))
    items = np.stack([rows, np.zeros_like(rows)], axis=1)
    own = np.array(trainer.train.ids)
    for seed in range(5):
        trainer.losses("selector", trainer.train, items, rng=np.random.default_rng(seed))
    assert len(asked) == 5  # one O_init per trajectory of each batch
    for condition in asked:
        assert [i.split("-")[0] for i in own[condition]] == [i.split("-")[0] for i in own[rows]]  # the same object
    assert any((c != rows).any() for c in asked)  # and not always the trajectory's own O_init
    asked.clear()
    trainer.losses("selector", trainer.train, items)  # no rng: a validation batch, each its own O_init
    assert all((a == rows).all() for a in asked)
    with pytest.raises(ValueError, match="selector_condition"):
        dataclasses.replace(TINY, selector_condition="scene")


def test_known_clusters_replace_the_posterior_and_score_it(tmp_path):
    log_qc = torch.log_softmax(torch.tensor([[0.0, 1.0, 2.0], [2.0, 0.0, 0.0]]), dim=-1)
    known = torch.tensor([0, -1])
    replaced = with_known_clusters(log_qc, known)
    assert torch.exp(replaced[0]).tolist() == pytest.approx([1.0, 0.0, 0.0], abs=1e-9)
    assert torch.equal(replaced[1], log_qc[1])  # unknown: the posterior
    assert known_cluster_loss(log_qc, known).tolist() == pytest.approx([-log_qc[0, 0].item(), 0.0])
    # through the selector loss: the term is weighted in, and the clusters of the batch change the ELBO
    data, _ = make_dataset(4, resolution=32, seed=1)
    trainer = Trainer(TINY, data, None, PLACEMENT, perception_record({"synthetic": 1}), "synthetic", tmp_path,
                      init_distributed("cpu"), show_progress=False)
    views, z = data.selector_batch(np.arange(4))
    eps = trainer.selector.standardise(z)
    noise = trainer.selector.draw_noise(4, torch.Generator().manual_seed(7))
    clusters = torch.tensor([0, 1, -1, 1])
    free, _, _ = selector_loss(trainer.selector, views, eps, TINY.elbo, noise)
    off, _, metrics = selector_loss(trainer.selector, views, eps, dataclasses.replace(TINY.elbo, known_cluster=0.0), noise,
                                    clusters=clusters)
    on, _, _ = selector_loss(trainer.selector, views, eps, dataclasses.replace(TINY.elbo, known_cluster=3.0), noise,
                             clusters=clusters)
    assert metrics["known_cluster"] > 0.0 and off.item() != pytest.approx(free.item())
    assert on.item() == pytest.approx(off.item() + 3.0 * metrics["known_cluster"], rel=1e-4)
