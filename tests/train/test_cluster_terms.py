"""The CGMVAE's cluster-usage terms (ElboWeights.cluster_balance, cluster_confidence): the imbalance is 0 for a batch
spread equally over the K clusters and log K for one cluster, and the selector loss adds exactly the weighted terms."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch

from actaim2.train.checkpoint import perception_record
from actaim2.train.distributed import init_distributed
from actaim2.train.elbo import cluster_imbalance, selector_loss
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
