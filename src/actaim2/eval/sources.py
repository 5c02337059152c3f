"""Where each method's keyposes come from, behind one interface: ``begin`` a sample, then ``next`` keypose.

* :class:`PolicySource` - a checkpoint served by :class:`actaim2.policy.inference.PolicyModel`
  (the same code ``policy_node`` runs): the mode eps drawn once from the robot-hidden initial
  views (a given cluster, or from the prior without clusters), then one keypose per phase
  predicted from the views observed just before it. ActAIM2, VQVAE-RVT, ActAIM (CVAE).
* :class:`GoalSource` - Goal-RVT: the predictor fed the true task embedding of a goal, computed
  from a robot-hidden render of the object set to the goal's end state (privileged: an oracle).
* :class:`SamplerSource` - a data-collection sampler: an action sequence drawn from the object
  cloud and IK-screened exactly as collection does, executed as its four keyposes.

A source that cannot produce a sample raises :class:`NoSample`; the sample counts as a failure.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import torch

from actaim2.artifact.serving import DEFAULT_SERVING
from actaim2.control.ik import IKSolver
from actaim2.data.actions import Sampler
from actaim2.data.collect import ik_reachable
from actaim2.data.gmm_sampler import GMMAdaptiveSampler
from actaim2.data.object_cloud import ObjectCloud
from actaim2.data.trajectory import Observation
from actaim2.eval.evalset import pseudo_order_seed
from actaim2.eval.methods import PSEUDO_CLUSTERS
from actaim2.eval.sim_views import ViewMaker, pictures
from actaim2.eval.tasks import EvalTask
from actaim2.keypose import Keypose
from actaim2.perception.extrinsic_refinement import ExtrinsicRefiner
from actaim2.policy.inference import ROLES, ModeSample, PolicyModel
from actaim2.policy.views import Views
from actaim2.robots import RobotSpec
from actaim2.sim.env import ResetInfo, SimEnv
from actaim2.sim.success import SUCCESS_FRACTION


class NoSample(RuntimeError):
    """The method produced no executable sample for this scene (the reason is the message).

    It still counts as a failed sample of its Mode SSR group (-1: none, e.g. no goal exists).
    """

    def __init__(self, reason: str, group: int = -1, repetition: int = -1):
        super().__init__(reason)
        self.group, self.repetition = group, repetition


@dataclass
class Scene:
    """What a source may look at when a sample begins (nothing privileged but ``info`` for the oracle)."""

    env: SimEnv
    info: ResetInfo
    init_pictures: Observation  # robot hidden, as O_init
    cloud: ObjectCloud  # the object cloud of O_init (samplers, the planner's obstacles)
    rng: np.random.Generator
    task: EvalTask


@dataclass
class Plan:
    """One sample under way: its Mode SSR group and the keypose of each phase."""

    group: int
    repetition: int
    next: Callable[[int, bool], Sequence[Keypose]]  # (phase, gripper closed now) -> the keypose, then its fallbacks
    details: dict = field(default_factory=dict)  # recorded with the result (cluster used, goal, confidences)
    eps: np.ndarray | None = None  # the interaction mode fed to the predictor (policy rows; not recorded)


def pseudo_group(key: str, slot: int) -> tuple[int, int]:
    """(pseudo-cluster, repetition) of an unclustered method's sample ``slot`` on object ``key``.

    Each repetition (8 consecutive slots) gives every pseudo-cluster one slot, in an order drawn
    per object and repetition. Not ``slot mod 8``: Data Collection's GMM sampler visits its
    clusters round robin by slot, so with 2, 4 or 8 clusters ``slot mod 8`` would name the cluster
    and the yardstick would not be a random partition (docs/decisions.md).
    """
    repetition, position = divmod(slot, PSEUDO_CLUSTERS)
    order = np.random.default_rng(pseudo_order_seed(key, repetition)).permutation(PSEUDO_CLUSTERS)
    return int(order[position]), repetition


def task_group(task: EvalTask) -> tuple[int, int]:
    """(group, repetition) of a sample drawn from a cluster or code, or of an unclustered method's (pseudo-cluster)."""
    if task.clusters:
        return task.cluster, task.slot // task.clusters
    return pseudo_group(task.obj.key, task.slot)


class ServedPolicy:
    """A policy checkpoint and the view makers of its two models (one when their views agree);
    ``alternatives``: fallback keyposes asked for with each one, ``guidance``: the mode guidance weight
    (both ``PolicyModel.predict_keypose``'s), ``noise_scale``: the spread of each mode draw
    (``PolicyModel.sample_mode``'s); ``refiner``: the view makers refine each picture's extrinsic from the
    robot (:class:`ViewMaker`)."""

    def __init__(self, model: PolicyModel, spec: RobotSpec, alternatives: int = 0, guidance: float = 0.0,
                 noise_scale: float = DEFAULT_SERVING.noise_scale, refiner: ExtrinsicRefiner | None = None):
        self.model, self.alternatives, self.guidance, self.noise_scale = model, alternatives, guidance, noise_scale
        makers: dict[str, ViewMaker] = {}
        self.makers = {}
        for role in ROLES:
            config = model.views_config(role)
            self.makers[role] = makers.setdefault(config.digest(), ViewMaker(config, spec, refiner))

    def views(self, role: str, observed: Observation, env: SimEnv) -> Views:
        return Views(0, self.makers[role].views(observed, env))

    def sample_mode(self, views: Views, cluster: int, seed: int) -> ModeSample:
        """The selector's draw for ``cluster`` (-1: drawn from the prior) at this source's noise scale."""
        return self.model.sample_mode(views, cluster, seed, self.noise_scale)

    def keyposes(self, scene: Scene, eps: np.ndarray, details: dict) -> Callable[[int, bool], Sequence[Keypose]]:
        """Predict each phase's keypose (and its fallbacks) from the views observed just before it (robot in the scene)."""
        confidences = details.setdefault("confidence", [])

        def next_keypose(phase: int, gripper_closed: bool) -> Sequence[Keypose]:
            views = self.views("predictor", pictures(scene.env, with_robot=True), scene.env)
            prediction = self.model.predict_keypose(views, eps, phase, gripper_closed, self.alternatives,
                                                    guidance=self.guidance)
            confidences.append(round(prediction.confidence, 4))
            return (prediction.keypose, *prediction.alternatives)

        return next_keypose


class PolicySource(ServedPolicy):
    def begin(self, scene: Scene) -> Plan:
        task = scene.task
        views = self.views("selector", scene.init_pictures, scene.env)
        sample = self.sample_mode(views, task.cluster if task.clusters else -1, task.sample_seed)
        group, repetition = task_group(task)
        details = {"cluster": sample.cluster}
        return Plan(group, repetition, self.keyposes(scene, sample.eps, details), details, sample.eps)


def feasible_goals(info: ResetInfo) -> list[tuple[str, int]]:
    """(DoF, direction) pairs the object can reach from its initial state: room for > 30 % of the range that way."""
    span = info.dof_upper - info.dof_lower
    goals = []
    for k, name in enumerate(info.dof_names):
        if span[k] <= 1e-9:
            continue
        if (info.dof_upper[k] - info.dof_initial[k]) / span[k] > SUCCESS_FRACTION:
            goals.append((name, 1))
        if (info.dof_initial[k] - info.dof_lower[k]) / span[k] > SUCCESS_FRACTION:
            goals.append((name, -1))
    return goals


def goal_pictures(env: SimEnv, info: ResetInfo, dof: str, direction: int) -> Observation:
    """Robot-hidden pictures of the object with ``dof`` at its limit in ``direction``; the state is restored after."""
    state = env.object_dof()
    goal = state.copy()
    k = info.dof_names.index(dof)
    goal[k] = info.dof_upper[k] if direction > 0 else info.dof_lower[k]
    env.object.set_qpos(goal)
    try:
        return pictures(env, with_robot=False)
    finally:
        env.object.set_qpos(state)


class GoalSource(ServedPolicy):
    """Goal-RVT: goal g = slot mod (number of feasible goals), so the goals are visited in turn."""

    def __init__(self, model: PolicyModel, spec: RobotSpec, encoder, alternatives: int = 0, guidance: float = 0.0):
        super().__init__(model, spec, alternatives, guidance)
        if model.selector is None:
            raise ValueError("the Goal-RVT checkpoint carries no selector, hence no z statistics to standardise the goal's z")
        self.encoder = encoder

    def begin(self, scene: Scene) -> Plan:
        goals = feasible_goals(scene.info)
        if not goals:
            raise NoSample("no DoF has room to move 30 % of its range either way")
        task = scene.task
        g = task.slot % len(goals)
        dof, direction = goals[g]
        init, final = self.encoder.encode([scene.init_pictures, goal_pictures(scene.env, scene.info, dof, direction)])
        with torch.no_grad():
            eps = self.model.selector.standardise(torch.from_numpy(np.asarray(init - final, np.float32))[None])[0]
        details, eps = {"goal": [dof, direction]}, eps.cpu().numpy()
        return Plan(g, task.slot // len(goals), self.keyposes(scene, eps, details), details, eps)


class SamplerSource:
    """A collection sampler; ``samplers`` maps object keys to their own (GMM), or None for one shared sampler."""

    def __init__(self, sampler: Sampler | None, samplers: dict[str, Sampler] | None, screen: IKSolver,
                 home: np.ndarray, max_samples: int):
        self.sampler, self.samplers, self.screen, self.home, self.max_samples = sampler, samplers, screen, home, max_samples

    def begin(self, scene: Scene) -> Plan:
        task = scene.task
        sampler = self.sampler if self.samplers is None else self.samplers.get(task.obj.key)
        group, repetition = task_group(task)
        if sampler is None:
            raise NoSample(f"no sampler for {task.obj.key}", group, repetition)
        # A GMM-adaptive sampler's own modes: the cluster this slot draws from, recorded so that
        # its Mode SSR can be counted by its components as well as by pseudo-clusters.
        details = ({"gmm_cluster": sampler.cluster_of(task.slot), "gmm_clusters": sampler.n_clusters}
                   if isinstance(sampler, GMMAdaptiveSampler) else {})
        for _ in range(self.max_samples):
            action = sampler.sample(scene.cloud, scene.rng, task.slot)
            if action is None:
                raise NoSample("sampler found no action", group, repetition)
            if ik_reachable(self.screen, self.home, action, scene.rng):
                keyposes = action.keyposes()
                return Plan(group, repetition, lambda phase, closed: keyposes[phase : phase + 1], details)
        raise NoSample("no sampled action passed the IK check", group, repetition)
