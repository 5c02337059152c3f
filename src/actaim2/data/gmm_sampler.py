"""GMM-based adaptive sampling (paper appendix, "3. GMM-based Adaptive Sampling"; Algorithm 1).

For one object, the task embeddings z of the trajectories collected so far are clustered with a
Gaussian mixture (each cluster ~ one interaction mode), a second Gaussian mixture is fitted to
the action sequences of every cluster, and new action sequences are drawn from the clusters in
turn, so each mode gets the same number of new trials however rare it was.

Which trajectories are clustered: those the *visual* label calls successful when there are
enough of them (the modes worth diversifying), otherwise all of them. z is high-dimensional,
so it is projected with PCA before clustering; the number of clusters is chosen by BIC up to
``max_clusters`` (the paper's hyper-parameter K). scikit-learn throughout.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn.decomposition import PCA
from sklearn.mixture import GaussianMixture

from actaim2.data.actions import ActionSequence
from actaim2.data.object_cloud import ObjectCloud
from actaim2.data.random_sampler import SamplingConfig, approach_is_free
from actaim2.profiling import timed


@dataclass(frozen=True)
class GMMConfig:
    max_clusters: int = 4  # K: interaction modes per object at most
    max_action_components: int = 3  # L: Gaussians per cluster over action sequences
    pca_dims: int = 8
    min_successes: int = 3  # fewer visually successful trajectories: cluster all of them
    points_per_component: int = 4  # a mixture component needs at least this many trajectories
    reg_covar: float = 1e-4


class GMMAdaptiveSampler:
    name = "gmm"

    def __init__(self, actions: np.ndarray, embeddings: np.ndarray, success: np.ndarray,
                 config: GMMConfig, sampling: SamplingConfig, seed: int = 0):
        """``actions``: (M, 13) :meth:`ActionSequence.vector` rows; ``embeddings``: (M, D) task
        embeddings z; ``success``: (M,) visual labels. Fitting is deterministic given ``seed``."""
        actions, embeddings, success = np.asarray(actions, float), np.asarray(embeddings, float), np.asarray(success, bool)
        if len(actions) != len(embeddings) or len(actions) != len(success):
            raise ValueError("actions, embeddings and success labels must have one row per trajectory")
        if len(actions) < 2:
            raise ValueError(f"GMM-adaptive sampling needs at least 2 collected trajectories, got {len(actions)}")
        self.config, self.sampling = config, sampling
        self.used_successes_only = bool(success.sum() >= config.min_successes)
        use = success if self.used_successes_only else np.ones(len(actions), bool)
        z = embeddings[use]
        dims = max(1, min(config.pca_dims, len(z) - 1, z.shape[1]))
        reduced = PCA(dims, random_state=seed).fit_transform(z)
        reduced = reduced / (reduced[:, 0].std() + 1e-9)  # one scale for all: noise directions stay small
        best = None
        for k in range(1, max(1, min(config.max_clusters, len(z) // config.points_per_component)) + 1):
            # Diagonal covariances: with tens of trajectories per object, full ones overfit and BIC
            # then prefers too few clusters.
            gmm = GaussianMixture(k, covariance_type="diag", reg_covar=1e-3, n_init=2, random_state=seed).fit(reduced)
            if best is None or gmm.bic(reduced) < best.bic(reduced):
                best = gmm
        labels = best.predict(reduced)
        self.action_gmms: list[GaussianMixture] = []
        cluster_actions = actions[use]
        for k in range(best.n_components):
            members = cluster_actions[labels == k]
            if len(members) < 2:
                continue
            n = max(1, min(config.max_action_components, len(members) // config.points_per_component))
            self.action_gmms.append(GaussianMixture(n, covariance_type="full", reg_covar=config.reg_covar,
                                                    random_state=seed).fit(members))
        if not self.action_gmms:
            raise ValueError("no interaction-mode cluster has 2 or more trajectories")
        self.cluster_sizes = np.bincount(labels, minlength=best.n_components)

    @property
    def n_clusters(self) -> int:
        return len(self.action_gmms)

    def cluster_of(self, index: int) -> int:
        """Round robin: the index-th adaptive trajectory of an object comes from this cluster."""
        return index % self.n_clusters

    @timed("sampling")
    def sample(self, cloud: ObjectCloud, rng: np.random.Generator, index: int) -> ActionSequence | None:
        """An action sequence from cluster ``cluster_of(index)``, collision- and reach-filtered."""
        gmm = self.action_gmms[self.cluster_of(index)]
        for _ in range(self.sampling.max_tries):
            component = rng.choice(gmm.n_components, p=gmm.weights_)
            v = rng.multivariate_normal(gmm.means_[component], gmm.covariances_[component])
            action = ActionSequence.from_vector(v)
            action.start_distance = self.sampling.start_distance
            if not (self.sampling.reachable(action.p0) and self.sampling.reachable(action.p1) and self.sampling.reachable(action.p2)):
                continue
            if approach_is_free(action.p1, action.R0, cloud.points, self.sampling):
                return action
        return None
