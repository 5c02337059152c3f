"""Teleop bags made in the tests: the scripted teleoperator's demonstrations on the three-drawer shelf,
executed in a SimEnv (Kinova, ``azure_kinect`` rig with its default sensor realism except its two
calibration errors, ray-cast pictures), written with the project's bag writer as ``bag_recorder``
writes a teleop session. The extrinsic jitter (5 mm, 0.5 deg per episode) and the systematic depth
error (up to 11 mm + 0.1 % of the distance per episode) put the arm 1-2 cm from where the
published /tf_static and the joint states say it is, beyond the self-filter's 10 mm margin (with
them, 45-70 % of the arm's pixels survived at two of these four placements, measured): a property
of the calibration, not of the conversion these tests check. Range noise, flying pixels, dropouts,
the nominal field of view and the registered colour camera stay on.

Topics and their content follow the recording of ``teleop_node``/``scripted_teleop`` + ``control_node``
+ ``sim_node``: ``/tf_static`` (world -> robot root, the camera's chain) once at the start,
``/episode`` START/END (object id, verdict), ``/interaction_mode`` (the label), ``/points2`` (the
driver's organized xyz+rgb cloud in ``depth_camera_link``), ``/joint_states`` and ``/keypose``.
Clouds are taken at rest: after START, before each keypose executes (O_i) and after the last one,
each with a joint state at its stamp and one 20 ms later; messages are logged 5 ms after their
stamp (transport). What each demonstration's observations really were is kept beside the bag,
with the renderer's segmentation, so a test can check the conversion against it.
"""
from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from actaim2.bags.definitions import MessageDefinitions
from actaim2.bags.metadata import TopicSpec
from actaim2.bags.writer import BagWriter
from actaim2.keypose import Keypose
from actaim2.perception.cloud_codec import encode

DEFINITIONS = MessageDefinitions(os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep))
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
for _name in ("Keypose", "InteractionMode", "EpisodeEvent"):
    TYPESTORE.register(get_types_from_msg(DEFINITIONS.text(f"actaim2_msgs/msg/{_name}"), f"actaim2_msgs/msg/{_name}"))
T = TYPESTORE.types
_INFINITE = QosTime(9223372036, 854775807)
TOPICS = {  # topic: (type, reliable, transient local)
    "/tf_static": ("tf2_msgs/msg/TFMessage", True, True),
    "/episode": ("actaim2_msgs/msg/EpisodeEvent", True, True),
    "/interaction_mode": ("actaim2_msgs/msg/InteractionMode", True, True),
    "/points2": ("sensor_msgs/msg/PointCloud2", False, False),
    "/joint_states": ("sensor_msgs/msg/JointState", True, False),
    "/keypose": ("actaim2_msgs/msg/Keypose", True, False),
}
CATEGORY, INSTANCE = "three_drawer_shelf", 0
LOG_DELAY_NS = 5_000_000
JOINT_STATE_AFTER_NS = 20_000_000


@dataclass(frozen=True)
class DemoSpec:
    seed: int
    drawer: int  # which drawer starts half-open (0 = bottom)
    label: str  # "pull" or "push"


@dataclass
class RecordedDemo:
    spec: DemoSpec
    object_id: str
    success: bool
    keyposes: list[Keypose]
    # "init", "o0".."o3", "final" -> (stamp ns, xyz (H, W, 3), rgb, robot mask (H, W) from the segmentation, joints)
    observations: dict[str, tuple] = field(default_factory=dict)


def _header(stamp_ns: int, frame: str = ""):
    return T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](stamp_ns // 10**9, stamp_ns % 10**9), frame)


def _spec(topic: str) -> TopicSpec:
    msgtype, reliable, latched = TOPICS[topic]
    qos = Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
              QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE, _INFINITE, _INFINITE,
              QosLiveliness.AUTOMATIC, _INFINITE, False)
    return TopicSpec(topic, msgtype, DEFINITIONS.definition(msgtype), DEFINITIONS.type_hash(msgtype), [qos])


def _serialize(topic: str, msg) -> bytes:
    return bytes(TYPESTORE.serialize_cdr(msg, TOPICS[topic][0]))


def _transform(parent: str, child: str, M: np.ndarray):
    from actaim2.geometry import matrix_to_pose

    p, q = matrix_to_pose(M)
    return T["geometry_msgs/msg/TransformStamped"](
        _header(0, parent), child,
        T["geometry_msgs/msg/Transform"](T["geometry_msgs/msg/Vector3"](*map(float, p)),
                                         T["geometry_msgs/msg/Quaternion"](*map(float, q))))


def cloud_msg(stamp_ns: int, xyz: np.ndarray, rgb: np.ndarray | None):
    encoded = encode(xyz, rgb)
    fields = [T["sensor_msgs/msg/PointField"](f.name, f.offset, f.datatype, f.count) for f in encoded.fields]
    return T["sensor_msgs/msg/PointCloud2"](_header(stamp_ns, "depth_camera_link"), encoded.height, encoded.width, fields,
                                            False, encoded.point_step, encoded.row_step,
                                            np.frombuffer(encoded.data, np.uint8), False)


def keypose_msg(stamp_ns: int, k: Keypose):
    pose = T["geometry_msgs/msg/Pose"](T["geometry_msgs/msg/Point"](*map(float, k.position)),
                                       T["geometry_msgs/msg/Quaternion"](*map(float, k.quat_xyzw)))
    return T["actaim2_msgs/msg/Keypose"](_header(stamp_ns, "world"), pose, bool(k.gripper_closed), int(k.phase))


class SimTeleop:
    """One simulator, planner and scripted teleoperator, reused for every bag of a test module."""

    def __init__(self) -> None:
        from actaim2.control.collision import CollisionChecker, Workspace
        from actaim2.control.ik import IKOptions, IKSolver
        from actaim2.control.model import RobotModel
        from actaim2.control.planner import KeyposePlanner, PlannerOptions
        from actaim2.rollout.scripted_teleop import ScriptedTeleoperator
        from actaim2.sim.env import SimEnv
        from actaim2.sim.sensor_noise import SensorNoise

        noise = dataclasses.replace(SensorNoise.preset("rig", "azure_kinect"), extrinsic_translation_std=0.0,
                                    extrinsic_rotation_std_deg=0.0, systematic_error=0.0, systematic_error_per_metre=0.0)
        self.env = SimEnv("kinova_j2s6s200", cameras="azure_kinect", render_path="raycast", noise=noise)
        robot = RobotModel(self.env.spec)
        checker = CollisionChecker(robot, Workspace())
        self.planner = KeyposePlanner(robot, checker, IKSolver(robot, checker, IKOptions()), PlannerOptions())
        self.teleoperator = ScriptedTeleoperator(self.env, seed=0)

    def record(self, path: Path, demos: list[DemoSpec], drop_topics: tuple[str, ...] = (),
               drop_phase: dict[int, int] | None = None) -> list[RecordedDemo]:
        """Write one bag with ``demos`` as consecutive episodes; ``drop_topics`` are not recorded,
        ``drop_phase`` {demo index: phase} leaves that keypose off /keypose (it still executes)."""
        from actaim2.control.executor import KeyposeRunner
        from actaim2.rollout.expert import ExpertTask
        from actaim2.rollout.scripted_teleop import judged_success
        from actaim2.rollout.sim_executor import SimEnvExecutor

        env, drop_phase = self.env, drop_phase or {}
        writer = BagWriter(path)
        ids = {topic: writer.add_topic(_spec(topic)) for topic in TOPICS if topic not in drop_topics}

        def put(topic: str, stamp_ns: int, msg) -> None:
            if topic in ids:
                writer.write(ids[topic], stamp_ns + LOG_DELAY_NS, _serialize(topic, msg))

        def now() -> int:
            return int(round(env.time * 1e9))

        def joint_state(stamp_ns: int) -> dict[str, float]:
            names, q, qd = env.joint_state()
            put("/joint_states", stamp_ns, T["sensor_msgs/msg/JointState"](_header(stamp_ns), list(names), q.astype(float),
                                                                         qd.astype(float), np.zeros(0)))
            return dict(zip(names, q.astype(float)))

        def observe(demo: RecordedDemo, name: str) -> None:
            """A cloud and the joint states around it; recorded as the observation ``name`` when given."""
            stamp = now()
            joints = joint_state(stamp)
            obs = env.observe(with_robot=True)
            frame = obs.frames["azure_kinect"]
            put("/points2", stamp, cloud_msg(stamp, frame.xyz, frame.rgb))
            env.step(int(round(JOINT_STATE_AFTER_NS / 1e9 / env.timestep)))
            joint_state(now())
            robot = np.isin(frame.segmentation, list(env.sim.robot_entity_ids()))
            demo.observations[name] = (stamp, frame.xyz.copy(), frame.rgb.copy(), robot, joints)

        edges = [_transform("world", env.spec.root_link, np.eye(4))]
        edges += [_transform(p, c, M) for p, c, M in env.rig.cameras["azure_kinect"].tf_chain]
        put("/tf_static", now(), T["tf2_msgs/msg/TFMessage"](edges))
        recorded = []
        for k, spec in enumerate(demos):
            fractions = [0.0, 0.0, 0.0]
            fractions[spec.drawer] = 0.5
            info = env.reset(CATEGORY, INSTANCE, seed=spec.seed, dof_fraction=fractions)
            task = ExpertTask(info.dof_names[spec.drawer], +1 if spec.label == "pull" else -1)
            plan = self.teleoperator.demo(task, np.random.default_rng(spec.seed))
            demo = RecordedDemo(spec, info.object_id, False, plan.keyposes)
            put("/interaction_mode", now(), T["actaim2_msgs/msg/InteractionMode"](_header(now(), "world"), -1,
                                                                                  np.zeros(0, np.float32), spec.label))
            put("/episode", now(), T["actaim2_msgs/msg/EpisodeEvent"](_header(now(), "world"), k, 0, info.object_id, False, ""))
            env.step(5)
            observe(demo, "init")
            runner = KeyposeRunner(self.planner, SimEnvExecutor(env), rng=np.random.default_rng(spec.seed))
            for keypose in plan.keyposes:
                observe(demo, f"o{keypose.phase}")
                if drop_phase.get(k) != keypose.phase:
                    put("/keypose", now(), keypose_msg(now(), keypose))
                runner.run(keypose, 0.5)
            observe(demo, "final")
            demo.success, _ = judged_success(task, info.dof_names, info.dof_initial, env.object_dof(), info.dof_lower,
                                             info.dof_upper)
            put("/episode", now(), T["actaim2_msgs/msg/EpisodeEvent"](_header(now(), "world"), k, 1, info.object_id,
                                                                      demo.success, spec.label))
            env.step(5)
            joint_state(now())
            recorded.append(demo)
        writer.close()
        return recorded


def rewrite(src: Path, dst: Path, keep) -> None:
    """Copy the bag ``src`` to ``dst`` message by message (same bytes, same log times), keeping the
    messages for which ``keep(topic, index)`` is true (index: among the topic's messages); a topic
    left without messages is not in the copy at all, as if it had never been recorded."""
    from actaim2.bags.source import BagSource

    source = BagSource(src, report=print)
    kept = [m for m in source.messages(set(source.topics)) if keep(m.topic, m.index)]
    writer = BagWriter(dst)
    ids = {topic: writer.add_topic(_spec(topic)) for topic in TOPICS if any(m.topic == topic for m in kept)}
    for m in kept:
        writer.write(ids[m.topic], m.timestamp, m.data)
    writer.close()
