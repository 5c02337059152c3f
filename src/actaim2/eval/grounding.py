"""Interaction-mode grounding (the paper's appendix experiment): find the mode that reaches a goal.

On one object, a target DoF and a goal end (open: its upper limit, close: its lower one), each
iteration executes one sample and gets the sparse reward r = 1 if |d - d_g| < d_eps (the DoF's
final state d within ``D_EPS`` of the goal d_g, both as fractions of its range; with d_eps = 0.2
from a half-open start this is "moved > 30 % the right way").

* ActAIM2: a Thompson-sampling bandit over its K clusters (Beta(1, 1) priors); a pull draws eps
  from the chosen cluster.
* CVAE (ActAIM) and VQVAE-RVT: the cross-entropy method over their continuous embedding (the
  CVAE's latent w, the VQ-VAE's code space), decoded to eps with the scene's view tokens:
  populations of ``CEM_POPULATION`` samples; up to ``CEM_ELITES`` rewarded ones refit the
  Gaussian (a population without any reward leaves it as it was: with a sparse reward, ranking
  zeros would only shrink the search at random).

Every iteration is a fresh scene (its own reset seed); runs of different seeds use different
scenes. One run = (method, target, seed) = ``iterations`` sequential samples, so runs are the
parallel unit. The plot shows the mean reward per iteration over seeds with a 95 % band.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from actaim2.eval.evalset import EvalObject
from actaim2.eval.sources import Plan, Scene, ServedPolicy, feasible_goals
from actaim2.eval.tasks import EvalTask

D_EPS = 0.2
CEM_POPULATION = 5
CEM_ELITES = 2
CEM_SMOOTHING = 0.7  # new = smoothing * elite statistics + (1 - smoothing) * old
CEM_MIN_STD = 0.05
GROUNDING_METHODS = ("actaim2", "actaim_cvae", "vqvae_rvt")
_SLOTS_PER_SEED = 100_000  # iteration i of seed s uses scene slot s * _SLOTS_PER_SEED + i


@dataclass(frozen=True)
class GroundingRun:
    method: str
    obj: EvalObject
    target: int  # +1: reach the DoF's upper limit (open), -1: its lower limit (close)
    seed: int
    iterations: int

    @property
    def key(self) -> str:
        return f"grounding|{self.method}|{self.obj.key}|{self.target:+d}|{self.seed}"


def reward(record: dict, dof: str, target: int) -> int:
    """1 when the DoF ended within D_EPS of the goal end, as fractions of its range."""
    final = record["initial"][dof] + record["fractions"][dof]
    goal = 1.0 if target > 0 else 0.0
    return int(abs(final - goal) < D_EPS)


class ThompsonBandit:
    """Beta-Bernoulli Thompson sampling over ``arms``."""

    def __init__(self, arms: int, rng: np.random.Generator):
        self.wins, self.losses, self.rng = np.ones(arms), np.ones(arms), rng

    def choose(self) -> int:
        return int(np.argmax(self.rng.beta(self.wins, self.losses)))

    def update(self, arm: int, r: int) -> None:
        self.wins[arm] += r
        self.losses[arm] += 1 - r


class CrossEntropySearch:
    """CEM over a continuous vector: Gaussian proposals, elites refit the mean and std."""

    def __init__(self, mean: np.ndarray, std: np.ndarray, rng: np.random.Generator):
        self.mean, self.std, self.rng = np.asarray(mean, float), np.asarray(std, float), rng
        self.population: list[tuple[np.ndarray, int]] = []

    def propose(self) -> np.ndarray:
        return self.mean + self.std * self.rng.standard_normal(self.mean.shape)

    def update(self, vector: np.ndarray, r: int) -> None:
        self.population.append((vector, r))
        if len(self.population) < CEM_POPULATION:
            return
        rewarded = [v for v, r in self.population if r > 0][:CEM_ELITES]
        self.population = []
        if not rewarded:  # a sparse reward all zero says nothing about where to go: keep searching as before
            return
        elites = np.stack(rewarded)
        self.mean = CEM_SMOOTHING * elites.mean(axis=0) + (1 - CEM_SMOOTHING) * self.mean
        self.std = np.maximum(CEM_SMOOTHING * elites.std(axis=0) + (1 - CEM_SMOOTHING) * self.std, CEM_MIN_STD)


class _ChosenEps(ServedPolicy):
    """A policy source whose eps comes from the search: a bandit's cluster or a CEM vector decoded with the scene."""

    def __init__(self, served: ServedPolicy):
        self.model, self.makers, self.alternatives, self.guidance = served.model, served.makers, served.alternatives, served.guidance
        self.noise_scale = served.noise_scale
        self.arm: int | None = None
        self.vector: np.ndarray | None = None

    def begin(self, scene: Scene) -> Plan:
        views = self.views("selector", scene.init_pictures, scene.env)
        if self.arm is not None:
            eps = self.sample_mode(views, self.arm, scene.task.sample_seed).eps
        else:
            selector = self.model.selector
            with torch.no_grad():
                tokens, _ = selector.condition(torch.from_numpy(views.data)[None].to(self.model.device))
                latent = torch.from_numpy(self.vector.astype(np.float32))[None].to(self.model.device)
                eps = selector.decoder(latent, tokens)[0].float().cpu().numpy()
        details: dict = {"cluster": self.arm if self.arm is not None else -1}
        return Plan(-1, -1, self.keyposes(scene, eps, details), details, eps)


def cem_start(selector) -> tuple[np.ndarray, np.ndarray]:
    """CEM's initial Gaussian: the CVAE's prior N(0, I); the VQ-VAE's codebook mean and spread."""
    if selector.config.kind == "vqvae":
        book = selector.codebook.detach().float().cpu().numpy()
        return book.mean(axis=0), np.maximum(book.std(axis=0), CEM_MIN_STD)
    return np.zeros(selector.config.latent_dim), np.ones(selector.config.latent_dim)


def run_grounding(worker, run: GroundingRun) -> dict:
    """One (method, target, seed) run: ``iterations`` samples; returns {key, dof, rewards, choices}."""
    from actaim2.eval.episode import run_sample

    served = worker.source(run.method)
    source = _ChosenEps(served)
    rng = np.random.default_rng([run.seed, zlib.crc32(run.key.encode())])
    clusters = served.model.clusters
    search = ThompsonBandit(clusters, rng) if run.method == "actaim2" else CrossEntropySearch(*cem_start(served.model.selector), rng)
    info = worker.env.reset(run.obj.category if not run.obj.folder else None, max(run.obj.instance, 0),
                            folder=run.obj.folder or None, dof_fraction=worker.setup.dof_fraction)
    both = [d for d, _ in feasible_goals(info) if (d, 1) in feasible_goals(info) and (d, -1) in feasible_goals(info)]
    if not both:
        raise ValueError(f"{run.obj.key} has no DoF that can be moved both ways from its initial state")
    dof, rewards, choices = both[0], [], []
    for i in range(run.iterations):
        if isinstance(search, ThompsonBandit):
            source.arm = search.choose()
            choice = source.arm
        else:
            source.vector = search.propose()
            choice = [round(float(v), 3) for v in source.vector[:4]]
        task = EvalTask(run.method, run.obj, run.seed * _SLOTS_PER_SEED + i, source.arm if source.arm is not None else -1, clusters)
        record = run_sample(worker.env, worker.planner, worker.executor, worker.cloud_config, source, task,
                            worker.setup.dof_fraction, worker.setup.velocity_scaling)
        r = reward(record, dof, run.target)
        search.update(source.arm if isinstance(search, ThompsonBandit) else source.vector, r)
        rewards.append(r)
        choices.append(choice)
    return {"key": run.key, "method": run.method, "object": run.obj.key, "target": run.target, "seed": run.seed,
            "dof": dof, "rewards": rewards, "choices": choices}


def reward_plot(results: list[dict], path: Path) -> None:
    """Mean reward per iteration over seeds, 95 % band (normal approximation over seeds), per target."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from actaim2.eval.methods import METHODS

    targets = sorted({r["target"] for r in results}, reverse=True)
    fig, axes = plt.subplots(1, len(targets), figsize=(5.5 * len(targets), 4), squeeze=False)
    for ax, target in zip(axes[0], targets):
        for method in GROUNDING_METHODS:
            runs = np.array([r["rewards"] for r in results if r["method"] == method and r["target"] == target], float)
            if runs.size == 0:
                continue
            x = np.arange(1, runs.shape[1] + 1)
            mean = runs.mean(axis=0)
            half = 1.96 * runs.std(axis=0, ddof=1) / np.sqrt(len(runs)) if len(runs) > 1 else np.zeros_like(mean)
            ax.plot(x, mean, label=f"{METHODS[method].title} ({'bandit' if method == 'actaim2' else 'CEM'}, {len(runs)} seeds)")
            ax.fill_between(x, np.clip(mean - half, 0, 1), np.clip(mean + half, 0, 1), alpha=0.2)
        ax.set_title(f"{results[0]['object']} {results[0]['dof']}: {'open' if target > 0 else 'close'}")
        ax.set_xlabel("iteration")
        ax.set_ylabel("reward")
        ax.set_ylim(-0.05, 1.05)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
