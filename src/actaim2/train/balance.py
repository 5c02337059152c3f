"""Cluster-balanced keyframe draws for the predictor phase (``predictor_balance: cluster``).

The evaluation, like the policy node, asks for each of the K clusters equally often, while the
predictor learns from keyframes in the proportions collection found them: on ``data/v2s`` an object
can hold 11 of its 22 trajectories in one cluster and 1 in another. A rare cluster's keyposes, which
are mostly its rarer outcomes, are then learnt from a few keyframes per epoch. Weighting the draw so
that within each object every cluster present carries an equal share of the object's keyframe mass
is an importance weighting towards the distribution the policy is served under. It reads no outcome
label: each trajectory's cluster is the one its true eps is quantised to on its own O_init
(``served_eps.nearest_centre_pools``), the object's total mass is unchanged.
"""
from __future__ import annotations

import numpy as np


def cluster_balanced_weights(objects: np.ndarray, clusters: np.ndarray) -> np.ndarray:
    """(N,) weight per trajectory: its object's count split equally over the clusters present, then over
    that cluster's trajectories. An object whose trajectories share one cluster keeps weight 1 each."""
    objects, clusters = np.asarray(objects), np.asarray(clusters)
    if objects.shape != clusters.shape:
        raise ValueError(f"one cluster per trajectory: {objects.shape} objects, {clusters.shape} clusters")
    weights = np.empty(len(objects), np.float64)
    for obj in np.unique(objects):
        members = objects == obj
        present, counts = np.unique(clusters[members], return_counts=True)
        share = members.sum() / len(present)
        for cluster, count in zip(present, counts):
            weights[members & (clusters == cluster)] = share / count
    return weights
