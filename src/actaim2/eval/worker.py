"""One evaluation worker: a simulator, the keypose planner and the methods' sources, in one process.

Built once per process (a pool worker, a Ray actor, or the main process with ``--workers 0``)
from a picklable :class:`WorkerSetup`; checkpoints and samplers are loaded on first use. The
planner and the IK screen are built as data collection builds them (``actaim2.data.collect``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Sequence

from actaim2.artifact.serving import DEFAULT_SERVING
from actaim2.control.planner import POLICY_PLANNER
from actaim2.data.collect import PRECHECK_IK_RESTARTS, CollectConfig

_COLLECT_DEFAULTS = {f.name: f.default for f in dataclasses.fields(CollectConfig)}


@dataclass(frozen=True)
class WorkerSetup:
    robot: str
    rig: str  # camera rig of the simulator (the checkpoints' perception configuration's)
    render_path: str  # resolved: "sapien" or "raycast"
    center: tuple[float, float, float]  # workspace cube (object cloud)
    half_extent: float
    checkpoints: dict[str, str] = field(default_factory=dict)  # method -> checkpoint stem
    encoder: str | None = None  # Goal-RVT's image encoder E (the dataset's)
    gmm: dict | None = None  # object key -> fitted GMMAdaptiveSampler (Data Collection)
    randomisation: dict | None = None  # DomainRandomisation.to_dict() of every reset (None: the rig's own sensor model)
    dof_fraction: float = _COLLECT_DEFAULTS["dof_fraction"]
    velocity_scaling: float = _COLLECT_DEFAULTS["velocity_scaling"]
    max_samples: int = _COLLECT_DEFAULTS["max_samples"]
    device: str = "cpu"
    hand_half_turn: bool = POLICY_PLANNER.hand_half_turn  # PlannerOptions.hand_half_turn for every row's keyposes
    keypose_alternatives: int = DEFAULT_SERVING.keypose_alternatives  # fallback rotations of each policy keypose (policy rows)
    mode_guidance: float = DEFAULT_SERVING.mode_guidance  # models/mode_guidance.py's weight for every policy keypose (policy rows)
    noise_scale: float = DEFAULT_SERVING.noise_scale  # spread of every policy row's mode draw (PolicyModel.sample_mode)
    refine_extrinsic: bool = False  # policy rows' views: each picture's extrinsic refined from the robot first (ViewMaker)


class EvalWorker:
    def __init__(self, setup: WorkerSetup):
        import torch

        from actaim2.control.collision import CollisionChecker
        from actaim2.control.ik import IKOptions, IKSolver
        from actaim2.control.model import RobotModel
        from actaim2.control.planner import KeyposePlanner, PlannerOptions
        from actaim2.data.object_cloud import CloudConfig
        from actaim2.rollout.sim_executor import SimEnvExecutor
        from actaim2.sim.env import SimEnv
        from actaim2.sim.randomisation import DomainRandomisation

        torch.set_num_threads(1)  # one core per worker: intra-op threads would only contend
        self.setup = setup
        randomisation = DomainRandomisation.from_dict(setup.randomisation) if setup.randomisation is not None else None
        self.env = SimEnv(setup.robot, cameras=setup.rig, render_path=setup.render_path, randomisation=randomisation)
        robot = RobotModel(self.env.spec)
        checker = CollisionChecker(robot)
        self.planner = KeyposePlanner(robot, checker, IKSolver(robot, checker), PlannerOptions(hand_half_turn=setup.hand_half_turn))
        self.screen_ik = IKSolver(robot, checker, IKOptions(restarts=PRECHECK_IK_RESTARTS))
        self.executor = SimEnvExecutor(self.env)
        self.cloud_config = CloudConfig(center=tuple(setup.center), half_extent=setup.half_extent)
        self.sources: dict = {}

    def source(self, method: str):
        if method not in self.sources:
            self.sources[method] = self._build(method)
        return self.sources[method]

    def _build(self, method: str):
        from actaim2.data.random_sampler import RandomSampler, SamplingConfig
        from actaim2.eval.checkpoints import perception_of
        from actaim2.eval.sources import GoalSource, PolicySource, SamplerSource
        from actaim2.perception.extrinsic_refinement import ExtrinsicRefiner, RobotSurface
        from actaim2.policy.inference import PolicyModel

        s, spec = self.setup, self.env.spec
        if method == "random":
            return SamplerSource(RandomSampler(SamplingConfig.for_robot(spec)), None, self.screen_ik, spec.home, s.max_samples)
        if method == "data_collection":
            return SamplerSource(None, s.gmm or {}, self.screen_ik, spec.home, s.max_samples)
        stem = s.checkpoints[method]
        model = PolicyModel.load(stem, perception_of(stem), s.device)
        if method == "goal_rvt":
            from actaim2.data.encoder import ImageEncoder

            return GoalSource(model, spec, ImageEncoder.load(s.encoder), s.keypose_alternatives, s.mode_guidance)
        refiner = ExtrinsicRefiner(RobotSurface(spec)) if s.refine_extrinsic else None
        return PolicySource(model, spec, s.keypose_alternatives, s.mode_guidance, s.noise_scale, refiner)

    def run(self, task) -> dict:
        """The task's result record (an EvalTask's sample, or a GroundingRun's rewards); {key, error} when
        something broke (a rerun retries it)."""
        from actaim2.eval.grounding import GroundingRun, run_grounding

        try:
            if isinstance(task, GroundingRun):
                return run_grounding(self, task)
            return self.sample(task)
        except Exception as exc:  # one broken sample (a simulator error) must not end a 3-hour evaluation
            return {"key": task.key, "method": task.method, "error": repr(exc)}

    def sample(self, task) -> dict:
        """The record of an EvalTask's sample, every DoF starting at the setup's fraction of its range (a protocol
        with initial states or verdicts of its own overrides this)."""
        return self.episode(task, self.setup.dof_fraction)

    def episode(self, task, dof_fraction: float | Sequence[float]) -> dict:
        """:func:`actaim2.eval.episode.run_sample` of ``task``, the object's DoFs reset to ``dof_fraction`` of their ranges."""
        from actaim2.eval.episode import run_sample

        return run_sample(self.env, self.planner, self.executor, self.cloud_config, self.source(task.method), task,
                          dof_fraction, self.setup.velocity_scaling)
