"""The collection loop (paper Algorithm 1): explore, learn E, label, adapt, label again.

Stages, each resumable (a stored or skipped trajectory id is never run again):
  1. explore   random and heuristic-grasp trajectories on every object; each one given up on is
               replaced by one more random trajectory (top-up), so every object keeps its count
  2. encoder   the default encoder E is trained on the training split's observations (unless a
               file is given, e.g. a VGG-19 encoder)
  3. label     the moved parts' motion from O_init and O_final (part_motion.py), z = E(O_init) -
               E(O_final), the success model calibrated on the training split, visual labels
               written (labelling.py)
  4. adapt     per object, GMMs fitted on z and on the action sequences (gmm_sampler.py) and
               new trajectories drawn equally from every cluster; ``rounds`` > 1 refits between
               rounds with the new trajectories labelled, as Algorithm 1 iterates
  5. label     again, so every trajectory has a visual label

One trajectory: reset the object half-open (placement jitter from the trajectory's reset seed),
observe O_init (robot hidden) and O_0, build the object cloud from O_init, sample an action
sequence, check the arm reaches its three poses (IK), execute the four keyposes through the
control package's planner observing O_1..O_3 in between, observe O_final (robot hidden), read
the DoFs (privileged, for validation only). A keypose the planner refuses restarts the
trajectory with a new sample, up to ``max_attempts`` times.

With ``actions_per_placement`` N > 1, trajectories k of one sampler on one object with the same
k // N share their reset seed (placement, randomisation draw): the same O_init then comes with
several actions and outcomes, the multimodality the mode selector's conditional prior models,
and the only case in which the predictor must read eps to tell the targets of one scene apart.

Workers are processes or Ray actors (actaim2.parallel, the executor evaluation uses), each with
its own simulator; the parent only writes, in task order. Every trajectory's
randomness comes from a seed derived from (seed, object, sampler, index), so a dataset is
reproducible from its seed whatever the worker count or interruptions.
"""
from __future__ import annotations

import json
import logging
import os
import time
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from actaim2.control.collision import CollisionChecker
from actaim2.control.executor import KeyposeRunner
from actaim2.control.ik import IKOptions, IKSolver
from actaim2.control.model import RobotModel
from actaim2.control.planner import KeyposePlanner
from actaim2.data.actions import ActionSequence, Sampler
from actaim2.data.gmm_sampler import GMMAdaptiveSampler, GMMConfig
from actaim2.data.grasp_sampler import HeuristicGraspSampler
from actaim2.data.labelling import (
    EMBEDDINGS_FILE,
    ENCODER_FILE,
    fit_default_encoder,
    label_dataset,
    measure_motions,
    visual_labels,
)
from actaim2.data.object_cloud import CloudConfig, object_cloud
from actaim2.data.random_sampler import RandomSampler, SamplingConfig
from actaim2.data.real_objects import FolderObject
from actaim2.data.splits import CALIBRATION_SPLITS, TRAINING_SPLITS, check_no_leak, split_of
from actaim2.data.stats import RUNS_FILE
from actaim2.data.storage import (
    SKIPPED_FILE,
    DatasetReader,
    DatasetWriter,
    EncodedTrajectory,
    encode_trajectory,
    object_of,
    trajectory_id,
)
from actaim2.data.trajectory import CameraImage, ObjectState, Observation, Trajectory
from actaim2.parallel import run_ordered
from actaim2.perception.config import (
    CAPTURE_FIELDS,
    RENDER_PATHS,
    PerceptionConfig,
    capture_part,
    check_compatible,
    load_perception_config,
)
from actaim2.progress import progress
from actaim2.robots import load_robot_spec
from actaim2.rollout.sim_executor import SimEnvExecutor
from actaim2.sim.contacts import ContactMonitor
from actaim2.sim.env import SimEnv
from actaim2.sim.objects.catalog import object_id
from actaim2.sim.objects.hulls import HullCache
from actaim2.sim.objects.prepare import prepare_objects
from actaim2.sim.randomisation import DomainRandomisation

EXPLORE_SAMPLERS = ("random", "grasp")
SAMPLER_CODES = {"random": 1, "grasp": 2, "gmm": 3}
PLACEMENT_CODE = 7  # derive_seed's last number for a shared reset, so it differs from every task seed
PRECHECK_IK_RESTARTS = 8
TOP_UP_ROUNDS = 3  # random replacements of skipped explore trajectories (replacements can be skipped too)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CollectConfig:
    out: Path
    objects: tuple[tuple[str, int], ...]  # catalogue (category, instance) pairs
    per_object: dict[str, int]  # sampler -> trajectories per object of a training split
    other_splits_share: float = 1.0  # objects outside the training splits get ceil(share x per_object) of each sampler
    workers: int = 2  # processes; 0 runs in this process (debugging, tests); Ray actors with ray_address
    ray_address: str | None = None  # run the trajectories on a Ray cluster (actaim2.parallel): auto, ray://host:port, local
    seed: int = 0
    robot: str = "panda"
    perception: str = "ring5"  # rig name or PerceptionConfig YAML: the rig, cube and render path of the pictures
    render_path: str = ""  # "" = the perception configuration's; "raycast" asks for ray casting explicitly
    allow_raycast: bool = False  # without a Vulkan device, fall back to ray casting instead of refusing
    dof_fraction: float = 0.5  # objects start half-open (paper)
    velocity_scaling: float = 0.5
    max_attempts: int = 4  # sample + execute attempts per trajectory
    max_samples: int = 12  # samples per attempt until one passes the IK check
    rounds: int = 1  # GMM refits (Algorithm 1's outer loop)
    encoder: Path | None = None  # a saved ImageEncoder; None trains the default into out/encoder.pt
    encoder_steps: int = 800
    encoder_trajectories: int = 150
    gmm: GMMConfig = field(default_factory=GMMConfig)
    show_progress: bool = True
    folders: tuple[FolderObject, ...] = ()  # real PartNet-Mobility folders (actaim2.data.real_objects)
    hull_cache: Path | None = None  # their convex decompositions (None: the default cache folder)
    randomisation: DomainRandomisation | None = None  # domain randomisation of every reset (actaim2.sim.randomisation)
    actions_per_placement: int = 1  # trajectories of one sampler sharing a reset (module docstring); 1: one reset each

    def __post_init__(self) -> None:
        if self.actions_per_placement < 1:
            raise ValueError(f"actions_per_placement must be >= 1, got {self.actions_per_placement}")


@dataclass(frozen=True)
class Task:
    tid: str
    category: str
    instance: int
    split: str
    sampler: str
    index: int  # this sampler's trajectory number on the object
    seed: int
    gmm: GMMAdaptiveSampler | None = None
    folder: str = ""  # a real object folder (instance -1), else the catalogue's (category, instance)
    reset_seed: int | None = None  # the placement shared with other tasks; None: every attempt draws its own


def derive_seed(seed: int, object_id: str, *numbers: int) -> int:
    """A 32-bit seed from the collection seed, an object and more non-negative numbers."""
    return int(np.random.SeedSequence([seed, zlib.crc32(object_id.encode()), *numbers]).generate_state(1)[0])


def from_sim(observation) -> Observation:
    """The simulator's :class:`actaim2.sim.observe.Observation` as stored camera pictures."""
    return {name: CameraImage(frame.rgb, frame.depth, observation.cameras[name].K, observation.cameras[name].T_world_optical)
            for name, frame in observation.frames.items()}


def collection_perception(config: CollectConfig) -> PerceptionConfig:
    """The perception configuration the pictures are taken under, its render path resolved.

    A rig's configuration names the renderer its training pictures come from (SAPIEN). Ray
    casting draws collision meshes in flat colours, other pictures than the models will be
    served, so collection takes it only when asked: ``render_path="raycast"``, or
    ``allow_raycast`` when no Vulkan device exists. Either way it is logged, and the render
    path is recorded in ``dataset.json``, where training runs check it.
    """
    from actaim2.sim.render_path import vulkan_device_error

    perception = load_perception_config(config.perception)
    requested = config.render_path or perception.render_path
    if requested not in RENDER_PATHS:
        raise ValueError(f"render path '{requested}' is not one of {RENDER_PATHS}")
    if requested == "raycast":
        log.warning("collecting ray-cast pictures (collision meshes, flat colours), as requested; dataset.json records it")
        return perception.replace(render_path="raycast")
    error = vulkan_device_error()
    if error is None:
        return perception.replace(render_path="sapien")
    if not config.allow_raycast:
        raise ValueError(f"no Vulkan device for SAPIEN rendering ({error}): collection does not fall back to ray casting "
                         f"by itself. Fix the device (VK_ICD_FILENAMES, see scripts/env.sh), or pass --allow-raycast to "
                         f"collect ray-cast pictures (recorded in dataset.json; models trained on them expect them)")
    log.warning("no Vulkan device (%s): collecting ray-cast pictures, as --allow-raycast permits; dataset.json records it", error)
    return perception.replace(render_path="raycast")


class TrajectoryCollector:
    """Runs tasks in one process: a simulator with the rig's cameras, the keypose planner, the samplers.

    The configuration's render path is taken as it is (``collect`` resolves it once, with
    :func:`collection_perception`): without a Vulkan device a ``sapien`` path fails here.
    """

    def __init__(self, config: CollectConfig):
        self.config = config
        perception = load_perception_config(config.perception)
        self.env = SimEnv(config.robot, cameras=perception.rig, render_path=config.render_path or perception.render_path,
                          hull_cache=config.hull_cache, randomisation=config.randomisation)
        robot = RobotModel(self.env.spec)
        checker = CollisionChecker(robot)
        self.planner = KeyposePlanner(robot, checker, IKSolver(robot, checker))
        # Screening samples needs no exhaustive search: few restarts, the planner retries properly.
        self.screen_ik = IKSolver(robot, checker, IKOptions(restarts=PRECHECK_IK_RESTARTS))
        self.cloud_config = CloudConfig(center=perception.center, half_extent=perception.half_extent)
        sampling = SamplingConfig.for_robot(self.env.spec)
        self.samplers: dict[str, Sampler] = {"random": RandomSampler(sampling), "grasp": HeuristicGraspSampler(self.cloud_config, sampling)}
        self.executor = SimEnvExecutor(self.env)
        self.contacts = ContactMonitor(self.env)

    def run(self, task: Task) -> EncodedTrajectory | dict:
        """The encoded trajectory, or a {id, reason} record when no attempt could be executed."""
        start = time.perf_counter()
        rng = np.random.default_rng(task.seed)
        sampler = task.gmm if task.sampler == "gmm" else self.samplers[task.sampler]
        reasons = []
        for attempt in range(self.config.max_attempts):
            result = self._attempt(task, sampler, rng)
            if isinstance(result, Trajectory):
                encoded = encode_trajectory(result)
                encoded.entry.update(index=task.index, action=[float(v) for v in ActionSequence.from_keyposes(result.keyposes).vector()],
                                     touched=result.info["touched"], attempts=attempt + 1, worker_seconds=round(time.perf_counter() - start, 3))
                return encoded
            reasons.append(result)
        return {"id": task.tid, "sampler": task.sampler, "category": task.category, "instance": task.instance, "reasons": reasons}

    def _attempt(self, task: Task, sampler: Sampler, rng: np.random.Generator) -> Trajectory | str:
        env = self.env
        reset_seed = task.reset_seed if task.reset_seed is not None else int(rng.integers(2**31))
        info = env.reset(task.category, task.instance, seed=reset_seed, dof_fraction=self.config.dof_fraction,
                         folder=task.folder or None)
        self.contacts.reset()
        observations = {"init": from_sim(env.observe(with_robot=False))}
        joints = {"init": self._joints()}
        cloud = object_cloud(observations["init"], self.cloud_config, rng)
        action = None
        for _ in range(self.config.max_samples):
            candidate = sampler.sample(cloud, rng, task.index)
            if candidate is None:
                return "sampler found no action"
            if self._reachable(candidate, rng):
                action = candidate
                break
        if action is None:
            return "no sampled action passed the IK check"
        self.planner.set_cloud(cloud.points)
        runner = KeyposeRunner(self.planner, self.executor, rng)
        keyposes = action.keyposes()
        outcomes = []
        for i, keypose in enumerate(keyposes):
            observations[f"o{i}"] = from_sim(env.observe(with_robot=True))
            joints[f"o{i}"] = self._joints()
            outcome = runner.run(keypose, self.config.velocity_scaling)
            if not outcome.success:
                return f"keypose {i}: {outcome.reason}"
            outcomes.append({"position_error": round(outcome.position_error, 4), "orientation_error": round(outcome.orientation_error, 4)})
        observations["final"] = from_sim(env.observe(with_robot=False))
        joints["final"] = self._joints()
        lower, upper = env.object_limits()
        return Trajectory(
            id=task.tid, object_id=info.object_id, category=task.category, instance=task.instance, split=task.split,
            sampler=task.sampler, seed=task.seed, keyposes=keyposes, observations=observations, robot_joints=joints,
            object_state=ObjectState(list(info.dof_names), lower, upper, info.dof_initial, env.object_dof()),
            info={"outcomes": outcomes, "reset_seed": info.seed, "touched": self.contacts.touched, "sampler_cluster": task.gmm.cluster_of(task.index) if task.gmm else None,
                  **({"randomisation": env.randomisation_draw} if env.randomiser is not None else {})},
        )

    def _reachable(self, action: ActionSequence, rng: np.random.Generator) -> bool:
        return ik_reachable(self.screen_ik, self.env.spec.home, action, rng)

    def _joints(self) -> dict[str, float]:
        names, positions, _ = self.env.joint_state()
        return {n: float(p) for n, p in zip(names, positions)}


def ik_reachable(ik: IKSolver, home: np.ndarray, action: ActionSequence, rng: np.random.Generator) -> bool:
    """IK (self-collision and floor checked) exists for p0, p1 and p2, each seeded from the last
    (from ``home`` for p0): the screen a sampled action passes before it is executed."""
    seed = home
    for position in (action.p0, action.p1, action.p2):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = action.R0, position
        result = ik.solve(T, seed, rng=rng, use_cloud=False)
        if not result.success:
            return False
        seed = result.angles
    return True


class CollectionWorker:
    """One worker's collector (simulator, planner, samplers), built once for all its tasks."""

    def __init__(self, config: CollectConfig):
        import torch

        torch.set_num_threads(1)  # one core per worker: intra-op threads would only contend
        self.collector = TrajectoryCollector(config)

    def run(self, task: Task) -> EncodedTrajectory | dict:
        """The collector's result; a task that raised comes back as an error record, so that one
        broken trajectory (a simulator error) does not end a long collection."""
        try:
            return self.collector.run(task)
        except Exception as exc:
            return {"id": task.tid, "sampler": task.sampler, "category": task.category, "instance": task.instance,
                    "reasons": [f"error: {exc!r}"]}


def _skipped_ids(out: Path) -> set[str]:
    path = out / SKIPPED_FILE
    return {json.loads(line)["id"] for line in path.read_text().splitlines() if line.strip()} if path.exists() else set()


def run_tasks(config: CollectConfig, writer: DatasetWriter, tasks: list[Task], stage: str) -> dict:
    """Execute tasks not yet stored or skipped; append results as they come (in task order).

    A task whose every attempt found no executable action is logged in skipped.jsonl and not
    retried; one that raised (counted as an error) is retried by the next run.
    """
    done = writer.ids | _skipped_ids(config.out)
    todo = [t for t in tasks if t.tid not in done]
    summary = {"stage": stage, "workers": config.workers, **({"ray": config.ray_address} if config.ray_address else {}),
               "trajectories": 0, "skipped": 0, "errors": 0, "seconds": 0.0, "already_done": len(tasks) - len(todo)}
    if not todo:
        return summary
    start = time.perf_counter()
    bar = progress(total=len(todo), desc=stage, unit="traj", disable=not config.show_progress)
    successes = 0
    with open(config.out / SKIPPED_FILE, "a") as skipped_log:
        try:
            for result in run_ordered(CollectionWorker, config, todo, config.workers, config.ray_address):
                if isinstance(result, EncodedTrajectory):
                    writer.append(result)
                    summary["trajectories"] += 1
                    successes += bool(result.entry["gt_success"])
                elif result["reasons"][-1].startswith("error:"):  # not logged as skipped: a resumed run retries it
                    summary["errors"] += 1
                    bar.write(f"{result['id']}: {result['reasons'][-1]}")
                else:
                    skipped_log.write(json.dumps(result) + "\n")
                    skipped_log.flush()
                    summary["skipped"] += 1
                bar.update(1)
                bar.set_postfix(stored=summary["trajectories"], skipped=summary["skipped"], errors=summary["errors"],
                                gt_success=f"{successes / max(summary['trajectories'], 1):.0%}")
        finally:
            bar.close()
    summary["seconds"] = round(time.perf_counter() - start, 2)
    summary["load_average"] = round(os.getloadavg()[0], 2)  # the machine's 1-minute load as the stage ended
    with open(config.out / RUNS_FILE, "a") as f:
        f.write(json.dumps(summary) + "\n")
    return summary


def stage_tasks(config: CollectConfig, sampler: str, indices: range, gmm: dict | None = None) -> list[Task]:
    """The tasks of one sampler on every object: trajectory numbers ``indices``, seeds derived.

    Objects outside the training splits (``TRAINING_SPLITS``) take the numbers below their share
    (``other_splits_share``) of the sampler's count. With ``gmm`` (object id -> fitted
    GMMAdaptiveSampler) objects without a sampler are left out.
    """
    tasks = []
    for oid, category, instance, split, folder in collection_objects(config):
        if gmm is not None and oid not in gmm:
            continue
        for k in (k for k in indices if k < per_object(config, sampler, split)):
            tasks.append(Task(trajectory_id(oid, sampler, k), category, instance, split, sampler, k,
                              derive_seed(config.seed, oid, SAMPLER_CODES[sampler], k), gmm[oid] if gmm is not None else None,
                              folder, shared_reset_seed(config, oid, sampler, k)))
    return tasks


def shared_reset_seed(config: CollectConfig, object_id: str, sampler: str, index: int) -> int | None:
    """The reset seed trajectory ``index`` shares with the others of its placement (``actions_per_placement``
    consecutive numbers of one sampler); None when every trajectory has its own."""
    n = config.actions_per_placement
    return None if n == 1 else derive_seed(config.seed, object_id, SAMPLER_CODES[sampler], index // n, PLACEMENT_CODE)


def collection_objects(config: CollectConfig) -> list[tuple[str, str, int, str, str]]:
    """(object id, category, instance, split, folder) of every object: catalogue ones (folder
    "") then real folders (instance -1)."""
    return ([(object_id(c, i), c, i, split_of(c, i), "") for c, i in config.objects]
            + [(f.object_id, f.category, -1, f.split, f.folder) for f in config.folders])


def top_up_tasks(config: CollectConfig) -> list[Task]:
    """One more random trajectory on an object for each of its explore trajectories given up on.

    A sampler can find nothing to do on an object (the grasp sampler on a lid lip it sees from
    one side only): random trajectories, indices past the random count, keep every object at
    its explore count. Derived from skipped.jsonl, so a resumed run asks for the same tasks.
    """
    skipped: dict[str, int] = {}  # object id: explore trajectories given up on
    path = config.out / SKIPPED_FILE
    for line in path.read_text().splitlines() if path.exists() else []:
        record = json.loads(line)
        if record["sampler"] in EXPLORE_SAMPLERS:
            oid = object_of(record["id"])
            skipped[oid] = skipped.get(oid, 0) + 1
    tasks = []
    for oid, category, instance, split, folder in collection_objects(config):
        start = per_object(config, "random", split)
        for k in range(start, start + skipped.get(oid, 0)):
            tasks.append(Task(trajectory_id(oid, "random", k), category, instance, split, "random", k,
                              derive_seed(config.seed, oid, SAMPLER_CODES["random"], k), None, folder,
                              shared_reset_seed(config, oid, "random", k)))
    return tasks


def per_object(config: CollectConfig, sampler: str, split: str) -> int:
    """Trajectories of ``sampler`` on one object of ``split``."""
    n = config.per_object.get(sampler, 0)
    return n if split in TRAINING_SPLITS else int(np.ceil(config.other_splits_share * n - 1e-9))


def _label(config: CollectConfig) -> dict:
    """Train the default encoder once if none was given, then (re)label everything."""
    encoder = config.encoder
    if encoder is None:
        encoder = config.out / ENCODER_FILE
        if not encoder.exists():
            reader = DatasetReader(config.out)
            model, _ = fit_default_encoder(reader, config.encoder_trajectories, config.encoder_steps, config.seed, config.show_progress)
            model.save(encoder)
    return label_dataset(config.out, encoder, CALIBRATION_SPLITS, workers=config.workers,
                         show_progress=config.show_progress)


def fit_gmm_samplers(config: CollectConfig, round_start: int) -> dict[str, GMMAdaptiveSampler]:
    """Per object, the GMM-adaptive sampler of the round whose first GMM index is ``round_start``.

    Fitted on the trajectories of the earlier stages and rounds only, labelled among themselves,
    in id order: a round interrupted and resumed draws exactly what it would have drawn.
    """
    reader = DatasetReader(config.out)
    with np.load(config.out / EMBEDDINGS_FILE) as f:
        z = dict(zip(f["ids"].tolist(), f["z"]))
    before = sorted((e for e in reader.entries if e["sampler"] != "gmm" or e["index"] < round_start), key=lambda e: e["id"])
    motions = measure_motions(config.out, workers=config.workers, show_progress=False)
    scores, model, _ = visual_labels(before, motions)
    sampling = SamplingConfig.for_robot(load_robot_spec(config.robot))
    by_object: dict[str, list[int]] = {}
    for k, e in enumerate(before):
        by_object.setdefault(e["object_id"], []).append(k)
    samplers = {}
    for oid, rows in by_object.items():
        if len(rows) < 2:
            continue
        samplers[oid] = GMMAdaptiveSampler(
            np.array([before[k]["action"] for k in rows]), np.stack([z[before[k]["id"]] for k in rows]),
            scores[rows] > model.threshold, config.gmm, sampling, seed=derive_seed(config.seed, oid, 0, round_start))
    return samplers


def check_resumable(info: dict, config: CollectConfig) -> None:
    """A dataset is resumed (or extended with more objects and trajectories) only with the seed
    and robot it was collected with: its trajectory ids name (object, sampler, index), and the
    same id under another seed or robot would be another trajectory."""
    for key, value in (("seed", config.seed), ("robot", config.robot)):
        if key in info and info[key] != value:
            raise ValueError(f"{config.out} was collected with {key} {info[key]!r}, not {value!r}: "
                             f"resume it with --{key} {info[key]}, or collect into another --out")
    shared = info.get("actions_per_placement", 1)  # absent: collected before the option, one reset each
    if shared != config.actions_per_placement:
        raise ValueError(f"{config.out} was collected with {shared} action(s) per placement, not "
                         f"{config.actions_per_placement}: resume it with --actions-per-placement {shared}, "
                         "or collect into another --out")
    randomisation = config.randomisation.to_dict() if config.randomisation is not None else None
    if info.get("domain_randomisation") != randomisation:  # absent: collected without
        raise ValueError(f"{config.out} was collected with domain randomisation {info.get('domain_randomisation')}, "
                         f"not {randomisation}: resume it with the same --domain-randomisation, or collect into another --out")


def collect(config: CollectConfig) -> dict:
    """Run every stage; returns the per-stage summaries and the labelling report."""
    import torch

    # One intra-op thread here too: on a loaded 2-core machine, two threads made encoder
    # training 5x slower (1.8 s against 0.36 s per step, measured) instead of faster.
    torch.set_num_threads(1)
    SamplingConfig.for_robot(load_robot_spec(config.robot))  # a robot without reach or hand geometry fails here, not in a worker
    n_gmm = config.per_object.get("gmm", 0)
    splits = {split for _, _, _, split, _ in collection_objects(config)}
    if n_gmm > 0 and not splits & set(CALIBRATION_SPLITS):
        raise ValueError(f"GMM-adaptive sampling needs visual labels, whose threshold is "
                         f"calibrated on {' or '.join(CALIBRATION_SPLITS)} objects: add some, or "
                         f"collect with --gmm 0")
    perception = collection_perception(config)
    config = replace(config, render_path=perception.render_path)  # workers take the resolved path as it is
    if (config.out / "dataset.json").exists():  # resuming: the pictures must be taken as before
        check_compatible(DatasetReader(config.out).perception_capture(), perception, CAPTURE_FIELDS, ("dataset", "this collection"))
        check_resumable(DatasetReader(config.out).info, config)
    config.out.mkdir(parents=True, exist_ok=True)
    info = {"rig": perception.rig, "perception": capture_part(perception), "robot": config.robot, "seed": config.seed,
            "objects": [list(o) for o in config.objects], "folders": [[f.folder, f.split] for f in config.folders],
            "per_object": config.per_object,
            "other_splits_share": config.other_splits_share, "dof_fraction": config.dof_fraction,
            "actions_per_placement": config.actions_per_placement}
    if config.randomisation is not None:  # each trajectory's draw is in its meta.json info
        info["domain_randomisation"] = config.randomisation.to_dict()
    if config.folders:  # their hulls before any worker loads them (a cached mesh costs a hash)
        prepare_objects([Path(f.folder) for f in config.folders], HullCache(config.hull_cache), max(1, config.workers))
    report: dict = {"stages": []}
    with DatasetWriter(config.out, info) as writer:
        explore = [t for s in EXPLORE_SAMPLERS for t in stage_tasks(config, s, range(config.per_object.get(s, 0)))]
        report["stages"].append(run_tasks(config, writer, explore, "explore"))
        for _ in range(TOP_UP_ROUNDS):
            summary = run_tasks(config, writer, top_up_tasks(config), "explore top-up")
            if summary["trajectories"] + summary["skipped"] + summary["errors"] == 0:  # nothing left to replace
                break
            report["stages"].append(summary)
        # labels need trajectories of a calibration split
        if n_gmm > 0 or any(e["split"] in CALIBRATION_SPLITS for e in writer.entries):
            report["labelling"] = _label(config)
        for r in range(config.rounds if n_gmm > 0 else 0):
            indices = range(r * n_gmm // config.rounds, (r + 1) * n_gmm // config.rounds)
            tasks = stage_tasks(config, "gmm", indices, fit_gmm_samplers(config, indices.start))
            report["stages"].append(run_tasks(config, writer, tasks, f"adapt round {r + 1}/{config.rounds}"))
            report["labelling"] = _label(config)
        check_no_leak(writer.entries)
    return report
