"""Recorded demonstrations -> the training-dataset format of collection (``data/storage.py``).

Each episode of each bag (:mod:`actaim2.finetune.bag_episodes`) becomes one stored trajectory,
so ``actaim2 train`` / ``actaim2 finetune`` read it as they read simulated data:

* keyframes: the four marked keyposes, O_0..O_3 the cloud sets at their marking, robot visible
  (training removes the robot itself with the stored joint positions, as for collected data);
* pictures: each organized cloud becomes a depth image (its z) and an RGB image, with the
  intrinsics fitted to the cloud (:mod:`actaim2.finetune.intrinsics`, residual recorded) and the
  extrinsics of the bag's ``/tf_static``; xyz-only clouds get fusion's grey, as the node sees them;
* joint positions per observation: ``/joint_states`` interpolated at each cloud's stamp
  (:class:`~actaim2.perception.joint_history.JointStateHistory`);
* extrinsics: each camera's, refined per episode from the robot itself before anything else
  (:mod:`actaim2.perception.extrinsic_refinement`: the arm's visual surface posed at each of the
  episode's clouds registered to them; the accepted fits combined, the ``/tf_static`` one kept when
  every fit is refused), stored in every picture of the episode and, with each fit, in the trajectory's
  info (``calibration``); ``refinement=None`` keeps ``/tf_static``'s;
* O_init and O_final: the first and last cloud sets of the episode with the robot removed by the
  self-filter posed at each cloud's stamp (a real arm cannot be hidden as the simulator hides it:
  its pixels take what the other of the two saw there, else "no return": :func:`fill_robot_pixels`),
  and the task embedding z = E(O_init) - E(O_final) with the
  encoder E given (the pretraining data's: its digest is recorded in dataset.json and embeddings.npz;
  given the policy checkpoint to fine-tune, a different E than the one it was trained with is refused);
* labels: the operator's verdict (END's success) is the label training selects on, the mode
  label (``/interaction_mode``) is kept in the index (``mode_label``) and the trajectory's info.

The capture fields of the perception configuration (rig, cube, robot filter) go into
dataset.json as collection writes them, so a training run under another configuration is
refused. Teleop demonstrations carry no privileged object state: ``gt_success`` is null.
Conversion problems never stop the run: a bag or an episode that cannot be converted is
reported and skipped (``bag2dataset.json`` lists what was converted and why the rest was not).
"""
from __future__ import annotations

import dataclasses
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from actaim2.data.encoder import ImageEncoder
from actaim2.data.labelling import EMBEDDINGS_FILE, encoder_digest
from actaim2.data.splits import TRAIN
from actaim2.data.storage import (
    DatasetWriter,
    EncodedTrajectory,
    encode_trajectory,
    trajectory_id,
    write_labels,
)
from actaim2.data.trajectory import CameraImage, ObjectState, Observation, Trajectory
from actaim2.finetune.bag_episodes import BagEpisode, BagProblem, Cloud, read_episodes
from actaim2.finetune.intrinsics import IntrinsicsFit, IntrinsicsFitError, fit_intrinsics
from actaim2.geometry import transform_points
from actaim2.perception.config import PerceptionConfig, capture_part
from actaim2.perception.extrinsic_refinement import (
    EpisodeCalibration,
    ExtrinsicRefiner,
    RefinementLimits,
    RobotSurface,
)
from actaim2.perception.fusion import NO_COLOUR
from actaim2.perception.joint_history import JointStateUnavailable
from actaim2.perception.self_filter import RobotSelfFilter
from actaim2.perception.static_tf import UnknownFrameError
from actaim2.progress import progress

SAMPLER = "teleop"  # the sampler name of demonstrations in the index
REPORT_FILE = "bag2dataset.json"
WORLD = "world"
ROBOT_HIDDEN = ("init", "final")


class EpisodeProblem(ValueError):
    """One episode cannot be converted; the message says why."""


class EncoderMismatchError(ValueError):
    """The encoder E given is not the one the policy to fine-tune was trained with."""


def check_checkpoint_encoder(checkpoint_stem: str | Path, encoder_path: str | Path, digest: str) -> None:
    """The checkpoint's selector learned task embeddings of one encoder E (``lineage.encoder_digest``,
    recorded by ``actaim2 train`` and ``actaim2 finetune``); demonstrations embedded by another E
    would ask it about a space it never saw. Raises naming both digests, or when none is recorded."""
    from actaim2.artifact import checkpoint

    _, meta = checkpoint.read(checkpoint_stem)
    recorded = (meta.get("lineage") or {}).get("encoder_digest")
    if recorded is None:
        raise EncoderMismatchError(f"checkpoint {checkpoint_stem} records no encoder digest (trained before checkpoints "
                                   f"recorded E, or on data without task embeddings): convert without --checkpoint and "
                                   f"fine-tune with --pretraining-data, which checks E against the training data")
    if recorded != digest:
        raise EncoderMismatchError(f"encoder {encoder_path} has digest {digest}, but checkpoint {checkpoint_stem} was "
                                   f"trained on task embeddings of encoder {recorded}: convert with its pretraining "
                                   f"data's encoder (<dataset>/encoder.pt, the one whose digest is {recorded})")


@dataclass
class BagReport:
    bag: str
    converted: list[str] = field(default_factory=list)  # trajectory ids
    problems: list[str] = field(default_factory=list)
    intrinsics: list[dict] = field(default_factory=list)  # one fit per converted cloud
    calibration: dict[str, dict] = field(default_factory=dict)  # trajectory id -> camera -> its extrinsic, why fits were refused


def rig_topics(config: PerceptionConfig) -> dict[str, str]:
    """Cloud topic -> camera name of the configuration's rig (``/points2`` -> ``azure_kinect``)."""
    from actaim2.sim.cameras import make_rig

    return {camera.topic: camera.name for camera in make_rig(config.rig, np.asarray(config.center))}


def object_category(object_id: str) -> tuple[str, int]:
    """(category, instance) of a catalogue id (``three_drawer_shelf_000``); other ids: (the id, 0)."""
    match = re.fullmatch(r"(.+)_(\d+)", object_id)
    return (match.group(1), int(match.group(2))) if match else (object_id or "unknown", 0)


def _picture(cloud: Cloud, fit: IntrinsicsFit, T_world_optical: np.ndarray, keep: np.ndarray | None = None) -> CameraImage:
    """The cloud as stored camera pictures; ``keep`` (H, W) False marks removed (robot) pixels."""
    depth = np.nan_to_num(cloud.xyz[..., 2], nan=0.0)
    rgb = np.broadcast_to(NO_COLOUR, cloud.xyz.shape).copy() if cloud.rgb is None else cloud.rgb.copy()
    if keep is not None:
        depth = np.where(keep, depth, 0.0)
        rgb[~keep] = 0
    return CameraImage(rgb, depth.astype(np.float32), fit.K, T_world_optical)


def fill_robot_pixels(init: CameraImage, final: CameraImage, removed_init: np.ndarray,
                      removed_final: np.ndarray) -> tuple[CameraImage, CameraImage]:
    """O_init and O_final of one fixed camera, each one's robot pixels taken from the other where
    the other saw the scene there.

    Why: E and the selector were pretrained on robot-hidden pictures the simulator renders without
    the arm, so the scene behind the arm is there. A real arm's pixels can only be removed, and
    holes where the arm stood at START and at END differ: E reads them as a change of the scene.
    The camera does not move between the two, so the other picture is the best view of what the
    arm hid; the drawer the arm held may have moved there, which this under-counts, never invents.
    Pixels removed in both stay empty. Measured on the stand-in's 57 demonstrations, z standardised
    as the selector does (``fit_statistics``) with the pretraining data's statistics: mean square
    2.2e3 with holes, 7.9e2 filled, against 2.0 for the pretraining data's successes; what is left
    is mostly arm the self-filter misses under the rig's calibration errors (docs/finetuning.md)."""
    if init.depth.shape != final.depth.shape:
        return init, final
    take_init = removed_final & ~removed_init & (init.depth > 0)
    take_final = removed_init & ~removed_final & (final.depth > 0)

    def filled(picture: CameraImage, source: CameraImage, take: np.ndarray) -> CameraImage:
        rgb, depth = picture.rgb.copy(), picture.depth.copy()
        rgb[take], depth[take] = source.rgb[take], source.depth[take]
        return CameraImage(rgb, depth, picture.K, picture.T_world_optical)

    return filled(init, final, take_final), filled(final, init, take_init)


class EpisodeConverter:
    """Turns :class:`BagEpisode` objects into trajectories and task embeddings."""

    def __init__(self, self_filter: RobotSelfFilter, encoder: ImageEncoder, refiner: ExtrinsicRefiner | None = None):
        self.self_filter = self_filter
        self.encoder = encoder
        self.refiner = refiner
        self._robot_joints = {self.self_filter.model.names[i] for i in range(1, self.self_filter.model.njoints)}

    def _joints(self, episode: BagEpisode, cloud: Cloud) -> dict[str, float]:
        try:
            joints = episode.joints_at(cloud.stamp_ns)
        except JointStateUnavailable as exc:
            raise EpisodeProblem(f"joint positions at the {cloud.camera} cloud of {cloud.stamp_ns / 1e9:.3f} s: {exc}") from exc
        if not self._robot_joints & set(joints):
            raise EpisodeProblem(f"/joint_states names {sorted(joints)[:8]}, none of the robot's joints "
                                 f"{sorted(self._robot_joints)[:8]}: the bag was recorded with another robot")
        return joints

    def _calibrations(self, episode: BagEpisode) -> dict[str, EpisodeCalibration]:
        """Each camera's extrinsic over the episode: ``/tf_static``'s, refined from its clouds when refining."""
        by_camera: dict[str, dict[int, Cloud]] = {}
        for clouds in episode.observations.values():
            for camera, cloud in clouds.items():
                by_camera.setdefault(camera, {})[cloud.stamp_ns] = cloud
        calibrations = {}
        for camera, clouds in sorted(by_camera.items()):
            frames = {c.frame_id for c in clouds.values()}
            try:
                T = episode.transforms.lookup(WORLD, frames.pop())
            except UnknownFrameError as exc:
                raise EpisodeProblem(f"camera {camera}: {exc}") from exc
            if frames:
                raise EpisodeProblem(f"camera {camera}: its clouds name more than one frame")
            calibrations[camera] = EpisodeCalibration(T) if self.refiner is None else self.refiner.calibrate(
                T, [(c.xyz, self._joints(episode, c)) for _, c in sorted(clouds.items())])
        return calibrations

    def convert(self, episode: BagEpisode, tid: str) -> tuple[Trajectory, np.ndarray, list[dict]]:
        """(trajectory, z, intrinsics fits) of one episode; EpisodeProblem when it cannot be converted."""
        observations: dict[str, Observation] = {}
        joints: dict[str, dict[str, float]] = {}
        fits, stamps = [], {}
        removed: dict[tuple[str, str], np.ndarray] = {}  # (observation, camera) -> robot pixels
        calibrations = self._calibrations(episode)
        for name, clouds in episode.observations.items():
            observations[name], stamps[name] = {}, {}
            for camera, cloud in sorted(clouds.items()):
                T = calibrations[camera].T_world_optical
                try:
                    fit = fit_intrinsics(cloud.xyz)
                except IntrinsicsFitError as exc:
                    raise EpisodeProblem(f"observation {name}, camera {camera}: {exc}") from exc
                fits.append({"observation": name, "camera": camera, **fit.to_json()})
                positions = self._joints(episode, cloud)
                keep = None
                if name in ROBOT_HIDDEN:
                    self.self_filter.set_joint_positions(list(positions), list(positions.values()))
                    points = transform_points(T, cloud.xyz.reshape(-1, 3))
                    valid = np.isfinite(points).all(axis=1)
                    keep = np.ones(len(points), bool)
                    keep[valid] = self.self_filter.keep_mask(points[valid])
                    keep = keep.reshape(cloud.xyz.shape[:2])
                    removed[name, camera] = ~keep
                observations[name][camera] = _picture(cloud, fit, T, keep)
                stamps[name][camera] = cloud.stamp_ns
            # one joint state per observation, as collection stores it: the first camera's stamp
            joints[name] = self._joints(episode, min(clouds.values(), key=lambda c: c.stamp_ns))
        for camera in set(observations["init"]) & set(observations["final"]):
            observations["init"][camera], observations["final"][camera] = fill_robot_pixels(
                observations["init"][camera], observations["final"][camera],
                removed["init", camera], removed["final", camera])
        init, final = self.encoder.encode([observations["init"], observations["final"]])
        category, instance = object_category(episode.object_id)
        trajectory = Trajectory(
            id=tid, object_id=episode.object_id, category=category, instance=instance, split=TRAIN, sampler=SAMPLER,
            seed=episode.episode, keyposes=episode.keyposes, observations=observations, robot_joints=joints,
            object_state=ObjectState([], np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0)),
            info={"bag": str(episode.bag), "episode": episode.episode, "mode_label": episode.label,
                  "operator_success": episode.success, "note": episode.note, "cloud_stamps_ns": stamps, "intrinsics": fits,
                  "calibration": {camera: c.to_json() for camera, c in calibrations.items()}},
        )
        return trajectory, (init - final).astype(np.float32), fits


def _demonstration(trajectory: Trajectory) -> EncodedTrajectory:
    """The encoded trajectory, its privileged ground truth marked unknown (a demonstration has none)."""
    encoded = encode_trajectory(trajectory)
    name, data = encoded.members[0]
    encoded.members[0] = (name, json.dumps({**json.loads(data), "gt_success": None}).encode())
    encoded.entry.update(gt_success=None, mode_label=trajectory.info["mode_label"], bag=trajectory.info["bag"],
                         episode=trajectory.info["episode"])
    return encoded


def bags_to_dataset(bags: Sequence[str | Path], out: str | Path, config: PerceptionConfig, robot: str,
                    encoder_path: str | Path, report: Callable[[str], None] = print,
                    checkpoint: str | Path | None = None,
                    refinement: RefinementLimits | None = RefinementLimits()) -> dict:
    """Convert every episode of ``bags`` into a new dataset at ``out``; returns the conversion report.
    With ``checkpoint`` (the policy to fine-tune), an encoder other than its E is refused first.
    ``refinement``: how each episode's extrinsics are refined from the robot (None: ``/tf_static``'s as they are)."""
    from actaim2.robots import load_robot_spec

    out = Path(out)
    if (out / "dataset.json").exists():
        raise FileExistsError(f"{out} already holds a dataset: convert into a new folder")
    digest = encoder_digest(Path(encoder_path))
    if checkpoint is not None:
        check_checkpoint_encoder(checkpoint, encoder_path, digest)
    encoder = ImageEncoder.load(encoder_path)
    spec = load_robot_spec(robot)
    refiner = None if refinement is None else ExtrinsicRefiner(RobotSurface(spec), refinement)
    converter = EpisodeConverter(RobotSelfFilter(spec, config.self_filter_margin), encoder, refiner)
    topics = rig_topics(config)
    info = {"rig": config.rig, "perception": capture_part(config), "robot": robot, "source": "bags",
            "bags": [str(b) for b in bags], "cloud_topics": topics,
            "extrinsic_refinement": None if refinement is None else dataclasses.asdict(refinement),
            "encoder": {"path": str(encoder_path), "digest": digest, "kind": encoder.spec.kind,
                        "input_size": [encoder.spec.height, encoder.spec.width],
                        "checked_against": None if checkpoint is None else str(checkpoint)}}
    reports: list[BagReport] = []
    z: dict[str, np.ndarray] = {}
    success: dict[str, bool] = {}
    with DatasetWriter(out, info) as writer, progress(total=len(bags), desc="bag2dataset",
                                                      unit="bag") as bar:
        for bag in bags:
            bag_report = BagReport(str(bag))
            reports.append(bag_report)

            def problem(text: str, bag_report: BagReport = bag_report) -> None:
                bag_report.problems.append(text)
                report(text)

            try:
                for episode in read_episodes(bag, topics, problem):
                    tid = trajectory_id(episode.object_id or "demo", SAMPLER, len(writer.entries))
                    try:
                        trajectory, z[tid], fits = converter.convert(episode, tid)
                        writer.append(_demonstration(trajectory))
                    except ValueError as exc:  # EpisodeProblem, or pictures the dataset format refuses
                        problem(f"{bag}: episode {episode.episode}: {exc}; skipped")
                        continue
                    success[tid] = episode.success
                    bag_report.converted.append(tid)
                    bag_report.intrinsics.extend(fits)
                    bag_report.calibration[tid] = {camera: {k: v for k, v in c.items() if k != "fits"} | {
                        "refused": [f["reason"] for f in c["fits"] if not f["accepted"]]}
                        for camera, c in trajectory.info["calibration"].items()}
            except BagProblem as exc:
                problem(f"{exc}; bag skipped")
            bar.update(1)
            bar.set_postfix(trajectories=len(writer.entries))
        entries = list(writer.entries)
    _write_labels(out, entries, z, success, digest)
    summary = _summary(reports, entries)
    (out / REPORT_FILE).write_text(json.dumps(summary, indent=2))
    return summary


def _write_labels(out: Path, entries: list[dict], z: dict[str, np.ndarray], success: dict[str, bool], digest: str) -> None:
    """embeddings.npz (as labelling writes it) and labels.jsonl, whose label is the operator's verdict
    (score 1 or 0: a demonstration has no visual score to threshold)."""
    ids = [e["id"] for e in entries]
    rows = np.stack([z[i] for i in ids]) if ids else np.zeros((0, 0), np.float32)
    np.savez(out / EMBEDDINGS_FILE, ids=np.array(ids), z=rows, encoder_digest=np.array(digest))
    write_labels(out, [{"id": i, "score": float(success[i]), "success": success[i], "source": "operator"} for i in ids])


def _summary(reports: list[BagReport], entries: list[dict]) -> dict:
    fits = [f for r in reports for f in r.intrinsics]
    labels: dict[str, int] = {}
    for e in entries:
        labels[e["mode_label"] or "<none>"] = labels.get(e["mode_label"] or "<none>", 0) + 1
    calibrations = [c for r in reports for cameras in r.calibration.values() for c in cameras.values()]
    return {
        "trajectories": len(entries),
        "extrinsics_refined": {"cameras": len(calibrations), "refined": sum(c["refined"] for c in calibrations),
                               "largest_correction_mm": max((1000 * c["translation_m"] for c in calibrations), default=None),
                               "largest_correction_deg": max((c["rotation_deg"] for c in calibrations), default=None)},
        "bags_converted": sum(1 for r in reports if r.converted),
        "bags_with_problems": sum(1 for r in reports if r.problems),
        "mode_labels": labels,
        "intrinsics_residual_px": {"rms_max": max((f["rms_px"] for f in fits), default=None),
                                   "max": max((f["max_px"] for f in fits), default=None)},
        "bags": [vars(r) for r in reports],
    }
