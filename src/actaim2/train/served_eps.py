"""Served eps: train the action predictor on the eps the selector draws, not on the true ones.

At serving the predictor reads eps drawn from one of the selector's clusters; in its pretraining
it reads the trajectory's *true* eps plus noise (``loop.Trainer.perturb_eps``). The two differ:
measured on the committed checkpoint (``actaim2 validate``), two drawn eps of one object lie 1.29
apart on average and two true eps 2.68, while the training noise puts two copies of one eps
about 2.8 apart. The predictor learned to treat the clusters' draws as one eps, and its points
reach the outcome a draw names no more often than shuffled names (46.2 against 45.2 % at REACH).

The remedy here trains on the served distribution. Before the predictor phase, every training
trajectory's O_init gets ``draws`` eps from each cluster. Each draw goes into the *pool* of the
trajectory of the same object whose true eps lies nearest. That is the labelling behind
validate's "2nd-mode SSR the clusters allow": the outcome a draw names is its nearest
demonstration's. A keyframe is then fed one draw from its trajectory's pool: the pair (draw,
keypose) is what an ideal predictor maps a served draw to. A trajectory no draw lies nearest to
is a mode the selector does not serve; its keyframes keep the true eps plus noise, so the
predictor keeps what it learned from them.

Neighbour eps (``neighbour_eps_pools``) fill the same pools with true eps instead: a trajectory's own
and those of its ``count`` nearest other trajectories of the same object. Why: each true eps is unique
to its trajectory, so a predictor fed it exactly (``fit_demos``) can key a keypose on it, placement
included; a cluster's samples on another placement of the object then act differently (in one
evaluation the most frequent outcome of a cluster's four samples on one object was only 73 % of them).
The nearest other true eps of an object has the trajectory's outcome 86 % of the time on ``data/v2s``,
its placement never: fed it, the predictor has to find where to act in the views and read from eps
only what the neighbours share.

Nearest-centre eps (``nearest_centre_pools``) quantise each true eps onto what the evaluation serves at
noise scale 0: the K clusters' noise-free eps computed on the trajectory's *own* O_init, of which the
one nearest its true eps. Why: served pools hand a trajectory draws computed on other placements' O_init
and leave it its true eps where no draw is nearest, so neither is what the predictor reads at s = 0,
where a cluster's eps is one point computed on the very views it is fed with. Quantised, a cluster's
centre on an O_init is trained towards the keyposes of the trajectories whose eps it stands for.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch

from actaim2.models.selector_base import ModeSelector
from actaim2.train.data import TrainingData
from actaim2.train.elbo import reconstruction


def nearest_true(drawn: torch.Tensor, true: torch.Tensor) -> np.ndarray:
    """(n,) index into ``true`` of each drawn eps's nearest true eps: the demonstration a draw names."""
    return torch.cdist(drawn, true).argmin(dim=1).cpu().numpy()


@torch.no_grad()
def served_eps_pools(selector: ModeSelector, data: TrainingData, objects: Sequence[str], rows: np.ndarray,
                     draws: int, device: torch.device, seed: int = 0, noise_scale: float = 1.0) -> list[np.ndarray]:
    """Per trajectory of ``data``, the (n, eps_size) drawn eps (at ``noise_scale``) whose nearest true eps is its own.

    Only the trajectories in ``rows`` (those the predictor learns keyposes from) receive draws and
    are candidates; every other trajectory's pool is empty. A selector without discrete modes
    (cvae) gives ``draws`` draws per trajectory, from its one Gaussian.
    """
    if draws < 1:
        raise ValueError(f"served eps need at least 1 draw per cluster, got {draws}")
    objects = np.asarray(objects)
    pools: list[list[np.ndarray]] = [[] for _ in range(len(data))]
    generator = torch.Generator(device=device).manual_seed(seed)
    clusters = range(selector.config.clusters) if selector.config.kind != "cvae" else [None]
    rows = np.asarray(rows)
    for obj in np.unique(objects[rows]):
        members = rows[objects[rows] == obj]
        views, z = data.selector_batch(members, device)
        true = selector.standardise(z)
        for k in range(len(members)):
            condition = views[k:k + 1].expand(draws, *views.shape[1:])
            drawn = torch.cat([selector.sample(condition, c, generator, noise_scale).eps for c in clusters])
            for eps, owner in zip(drawn.cpu().numpy(), nearest_true(drawn, true)):
                pools[members[owner]].append(eps)
    size = selector.config.eps_size
    return [np.stack(p).astype(np.float32) if p else np.zeros((0, size), np.float32) for p in pools]


@torch.no_grad()
def nearest_centre_pools(selector: ModeSelector, data: TrainingData, rows: np.ndarray, device: torch.device,
                         chunk: int = 64) -> tuple[list[np.ndarray], np.ndarray]:
    """Per trajectory of ``data``, a (1, eps_size) pool holding the noise-free eps of the cluster, among the K
    computed on its own O_init (``ModeSelector.cluster_centres``), nearest its true eps; empty outside ``rows``.
    Also the (len(rows),) cluster each of ``rows`` was quantised to. A selector without discrete modes is refused."""
    if selector.config.kind == "cvae":
        raise ValueError("nearest-centre eps need a selector with clusters; a cvae selector has one Gaussian")
    rows = np.asarray(rows)
    pools = [np.zeros((0, selector.config.eps_size), np.float32) for _ in range(len(data))]
    chosen = np.zeros(len(rows), np.int64)
    for start in range(0, len(rows), chunk):
        part = rows[start:start + chunk]
        views, z = data.selector_batch(part, device)
        centres = selector.cluster_centres(*selector.condition(views))  # (n, K, eps_size)
        nearest = reconstruction(centres, selector.standardise(z)[:, None]).argmin(dim=1)  # the coverage term's winner
        chosen[start:start + len(part)] = nearest.cpu().numpy()
        for row, eps in zip(part, centres[torch.arange(len(part), device=centres.device), nearest].cpu().numpy()):
            pools[row] = eps[None].astype(np.float32)
    return pools, chosen


def neighbour_eps_pools(true: np.ndarray, objects: Sequence[str], rows: np.ndarray, count: int) -> list[np.ndarray]:
    """Per trajectory of ``true`` (N, eps_size), the true eps of itself and of its ``count`` nearest other
    trajectories of the same object (fewer where the object has fewer); empty for trajectories not in ``rows``
    (those the predictor learns keyposes from). Any trajectory of the object may be a neighbour."""
    if count < 1:
        raise ValueError(f"neighbour eps need at least 1 neighbour, got {count}")
    objects = np.asarray(objects)
    pools = [np.zeros((0, true.shape[1]), np.float32) for _ in range(len(true))]
    for row in np.asarray(rows):
        others = np.flatnonzero((objects == objects[row]) & (np.arange(len(true)) != row))
        nearest = others[np.argsort(np.linalg.norm(true[others] - true[row], axis=1), kind="stable")[:count]]
        pools[row] = true[np.concatenate([[row], nearest])].astype(np.float32)
    return pools


def pick_from_pools(pools: list[np.ndarray], rows: np.ndarray,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(positions in ``rows`` whose pool holds draws, one draw from each of those pools)."""
    positions = np.flatnonzero([len(pools[r]) > 0 for r in rows])
    picked = [pools[rows[k]][rng.integers(len(pools[rows[k]]))] for k in positions]
    size = pools[0].shape[1] if pools else 0
    return positions, np.stack(picked) if picked else np.zeros((0, size), np.float32)
