"""fusion_node: camera clouds in, /fused_points, /ortho_views and /ortho_views/preview out.

A thin adapter over ``actaim2.perception``: it synchronises the cloud topics, looks up their
extrinsics (/tf_static or a calibration YAML; with ``refine_extrinsic``, corrected by registering the
robot itself to each camera's cloud every ``refine_extrinsic_period``, the last accepted correction
kept), keeps a short history of /joint_states so the
self-filter poses the robot as it stood at each cloud's stamp (``actaim2.perception.joint_history``),
and publishes what ``Perception.process`` returns. Bad input (empty or all-NaN
clouds, missing fields, unknown frames, stamps too far apart, nothing inside the workspace) is
reported once per cause and topic, throttled, and the set is dropped: nothing half-made is
ever published, and the node keeps running.

Processing runs in one worker thread that always takes the newest complete set and drops older
ones, while the executor thread keeps receiving: a slow set never queues stale clouds behind
it (latency stays one processing time), and receiving large clouds overlaps with fusing the
previous set (numpy and torch release the GIL).
"""
from __future__ import annotations

import array
import threading
import time
from functools import partial

import numpy as np
import torch
from actaim2_msgs.msg import OrthoViews
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Image, JointState, PointCloud2

from actaim2.perception.calibration import load_calibration
from actaim2.perception.cloud_codec import CloudFormatError
from actaim2.perception.config import load_perception_config
from actaim2.perception.extrinsic_refinement import ExtrinsicRefiner, RobotSurface
from actaim2.perception.fusion import CameraCloud
from actaim2.perception.joint_history import (
    DEFAULT_HISTORY,
    DEFAULT_MAX_EXTRAPOLATION,
    JointStateHistory,
    JointStateUnavailable,
)
from actaim2.perception.memory import keep_freed_memory
from actaim2.perception.ortho_views import VIEWS, rgb_mosaic
from actaim2.perception.pipeline import EmptyObservationError, Perception
from actaim2.perception.self_filter import RobotSelfFilter
from actaim2.perception.static_tf import StaticTransformBuffer, UnknownFrameError
from actaim2.perception.time_sync import ApproximateTimeSync
from actaim2.robots import load_robot_spec
from actaim2_ros.main import spin
from actaim2_ros.params import declare_parameters
from actaim2_ros.pointcloud2 import from_msg, to_msg
from actaim2_ros.stamps import stamp_ns
from actaim2_ros.transforms import listen_tf_static

VIEWS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)

PARAMETERS = {
    # name: (default, description)
    "cloud_topics": (["/points2"], "PointCloud2 topics to fuse (organized or not, any frame and layout)"),
    "sync_slop": (0.05, "s: clouds whose stamps lie within this window are fused together"),
    "calibration_file": ("", "extrinsics YAML (frame -> 4x4); empty = take them from /tf_static"),
    "world_frame": ("world", "frame of the fused cloud and the views"),
    "perception_config": (
        "azure_kinect",
        "rig name (ring5, azure_kinect: actaim2/perception/configs/<rig>.yaml) or a PerceptionConfig YAML: the cube, "
        "fusion, robot-hidden views and view rendering; its digest is stamped on every /ortho_views",
    ),
    "robot": ("panda", "robot preset or RobotSpec YAML whose collision geometry the self-filter removes"),
    "remove_robot_fused": (
        False, "remove robot points from /fused_points too (it then waits for /joint_states, as robot-hidden views do)"
    ),
    "joint_states_topic": ("/joint_states", "robot joint positions for the self-filter"),
    "joint_state_history": (DEFAULT_HISTORY, "s of /joint_states kept to pose the robot at each cloud's stamp"),
    "joint_state_max_extrapolation": (
        DEFAULT_MAX_EXTRAPOLATION,
        "s: a cloud stamped up to this long after the newest JointState is filtered with extrapolated joints; "
        "later ones are dropped with the reason logged",
    ),
    "joint_state_wait": (
        0.1, "s the worker waits for a JointState at or after a cloud's stamp (to interpolate) before extrapolating",
    ),
    "report_period": (10.0, "s: a given bad-input cause is logged at most once per period"),
    "alternate_views_topic": (
        "", "also publish views with the other robot-filter setting (robot visible when the configuration hides it, and "
            "the reverse), stamped with that configuration's digest: for a policy whose selector and predictor were "
            "trained on different ones (policy_node's predictor_views_topic); empty = not published",
    ),
    "torch_threads": (1, "CPU threads for fusion and rendering; 1 avoids OpenMP spin contention on small machines"),
    "refine_extrinsic": (
        False, "refine each camera's extrinsic by registering the robot's own surface (posed at the cloud's stamp) to "
               "its organized cloud, bounded and refused when the fit is poor (actaim2.perception.extrinsic_refinement): "
               "for a single-view rig with a hand-eye calibration; off for the calibrated ring5 rig",
    ),
    "refine_extrinsic_period": (10.0, "s between two refinements of a camera's extrinsic (the camera is fixed)"),
}


class ThrottledReporter:
    """Logs each cause at most once per period (rclpy's own throttle is per call site, not per cause)."""

    def __init__(self, node: Node, period: float) -> None:
        self._node = node
        self._period = period
        self._last: dict[str, float] = {}

    def __call__(self, cause: str, text: str) -> None:
        now = time.monotonic()
        if now - self._last.get(cause, -np.inf) >= self._period:
            self._last[cause] = now
            self._node.get_logger().warning(f"{text} (dropped; repeated at most every {self._period:g} s)")


class FusionNode(Node):
    def __init__(self) -> None:
        super().__init__("fusion_node")
        p = declare_parameters(self, PARAMETERS)
        torch.set_num_threads(int(p["torch_threads"]))
        self._topics = list(p["cloud_topics"])
        self._world = p["world_frame"]
        self._report = ThrottledReporter(self, float(p["report_period"]))

        config = load_perception_config(p["perception_config"])
        self._remove_robot_fused = bool(p["remove_robot_fused"])
        self._alternate = (config.replace(remove_robot_views=not config.remove_robot_views)
                           if p["alternate_views_topic"] else None)
        self._refiner = ExtrinsicRefiner(RobotSurface(load_robot_spec(p["robot"]))) if p["refine_extrinsic"] else None
        self._refine_period = float(p["refine_extrinsic_period"])
        self._corrections: dict[str, np.ndarray] = {}  # frame -> accepted world-frame correction of its extrinsic
        self._next_refinement: dict[str, float] = {}  # frame -> monotonic time of its next refinement
        needs_robot = self._remove_robot_fused or config.remove_robot_views or bool(self._alternate)
        self_filter = RobotSelfFilter(load_robot_spec(p["robot"]), config.self_filter_margin) if needs_robot else None
        self._perception = Perception(config, self_filter)
        self._digest = config.digest()
        self._has_preview = {"r", "g", "b", "occupancy"} <= set(config.channels)  # the mosaic needs colour
        # Outputs that wait for /joint_states; /fused_points unfiltered never does.
        self._waiting = [t for t, filtered in (("/fused_points", self._remove_robot_fused), ("/ortho_views", config.remove_robot_views),
                                               (p["alternate_views_topic"], self._alternate and self._alternate.remove_robot_views))
                         if filtered]
        self._joint_history = JointStateHistory(float(p["joint_state_history"]), float(p["joint_state_max_extrapolation"]))
        self._joint_wait = float(p["joint_state_wait"])
        self._joint_arrived = threading.Condition()  # guards the history: filled by the executor, read by the worker
        self._needs_joints = needs_robot
        self._pending: list[PointCloud2] | None = None
        self._wakeup = threading.Condition()
        self._running = True
        self._worker = threading.Thread(target=self._work, name="fusion_worker", daemon=True)

        self._tf = StaticTransformBuffer()
        if p["calibration_file"]:
            parent, transforms = load_calibration(p["calibration_file"])
            for child, T in transforms.items():
                self._tf.set_transform(parent, child, T)
        else:
            listen_tf_static(self, self._tf)
        self._sync = ApproximateTimeSync(len(self._topics), int(float(p["sync_slop"]) * 1e9))

        self._fused_pub = self.create_publisher(PointCloud2, "/fused_points", qos_profile_sensor_data)
        self._views_pub = self.create_publisher(OrthoViews, "/ortho_views", VIEWS_QOS)
        self._alternate_pub = (self.create_publisher(OrthoViews, p["alternate_views_topic"], VIEWS_QOS)
                               if self._alternate else None)
        self._preview_pub = self.create_publisher(Image, "/ortho_views/preview", qos_profile_sensor_data)
        for index, topic in enumerate(self._topics):
            self.create_subscription(PointCloud2, topic, partial(self._on_cloud, index), qos_profile_sensor_data)
        if needs_robot or self._refiner is not None:
            self.create_subscription(JointState, p["joint_states_topic"], self._on_joint_state, 10)
        self._worker.start()
        self.get_logger().info(
            f"fusing {self._topics} into '{self._world}' with perception configuration {config.rig} (digest {self._digest}: "
            f"cube {list(config.center)} +- {config.half_extent} m, {config.resolution} px views), extrinsics from "
            f"{p['calibration_file'] or '/tf_static'}{' refined from the robot' if self._refiner else ''}; "
            f"robot-filtered outputs waiting for {p['joint_states_topic']}: "
            f"{self._waiting or 'none'}"
        )

    def _on_joint_state(self, msg: JointState) -> None:
        if len(msg.position) != len(msg.name):
            self._report("joint_states", f"JointState with {len(msg.name)} names but {len(msg.position)} positions")
            return
        stamp = stamp_ns(msg.header.stamp)
        if stamp == 0:
            self._report("joint_states:stamp", "JointState without a stamp: it cannot be matched to the clouds' stamps")
            return
        with self._joint_arrived:
            self._joint_history.add(stamp, list(msg.name), list(msg.position))
            self._joint_arrived.notify_all()

    def _on_cloud(self, index: int, msg: PointCloud2) -> None:
        group = self._sync.add(index, stamp_ns(msg.header.stamp), msg)
        if group is None:
            if self._sync.last_spread_ns is not None:
                self._report(
                    "stamps",
                    f"cloud stamps {self._sync.last_spread_ns / 1e6:.1f} ms apart exceed sync_slop "
                    f"{self._sync.slop_ns / 1e6:.1f} ms",
                )
            return
        with self._wakeup:
            self._pending = group  # replaces a set the worker has not started: only the newest counts
            self._wakeup.notify()

    def _work(self) -> None:
        while True:
            with self._wakeup:
                self._wakeup.wait_for(lambda: self._pending is not None or not self._running)
                if not self._running:
                    return
                group, self._pending = self._pending, None
            try:
                self._process(group)
            except Exception as exc:  # noqa: BLE001 - a bug must not silently stop the worker thread
                self._report(f"error:{type(exc).__name__}", f"processing failed: {type(exc).__name__}: {exc}")

    def destroy_node(self) -> None:
        with self._wakeup:
            self._running = False
            self._wakeup.notify()
        self._worker.join(timeout=5.0)
        super().destroy_node()

    def _decode(self, topic: str, msg: PointCloud2) -> CameraCloud | None:
        try:
            cloud = from_msg(msg)
        except CloudFormatError as exc:
            self._report(f"format:{topic}", f"{topic}: unreadable PointCloud2: {exc}")
            return None
        if len(cloud.xyz) == 0:
            self._report(f"empty:{topic}", f"{topic}: empty cloud")
            return None
        if not np.isfinite(cloud.xyz).all(axis=1).any():
            self._report(f"nan:{topic}", f"{topic}: every point is NaN")
            return None
        try:
            T = self._tf.lookup(self._world, msg.header.frame_id)
        except UnknownFrameError as exc:
            self._report(f"frame:{topic}", f"{topic}: unknown frame '{msg.header.frame_id}': {exc}")
            return None
        return CameraCloud(cloud.xyz, cloud.rgb, self._corrections.get(msg.header.frame_id, np.eye(4)) @ T)

    def _refine(self, msgs: list[PointCloud2], clouds: list[CameraCloud]) -> list[CameraCloud]:
        """The clouds with the extrinsics of those due for a refinement refined from the robot in them; a refused
        fit keeps the last accepted correction (reason logged)."""
        now, out = time.monotonic(), []
        for topic, msg, cloud in zip(self._topics, msgs, clouds):
            frame = msg.header.frame_id
            if now < self._next_refinement.get(frame, -np.inf):
                out.append(cloud)
                continue
            self._next_refinement[frame] = now + self._refine_period
            if msg.height <= 1:
                self._report(f"refine:{topic}", f"{topic}: an unorganized cloud: its extrinsic is not refined")
                out.append(cloud)
                continue
            joints = self._joint_positions([stamp_ns(msg.header.stamp)], "the extrinsic is not refined")
            if joints is None:
                out.append(cloud)
                continue
            nominal = np.linalg.inv(self._corrections.get(frame, np.eye(4))) @ cloud.T_world_cloud
            fit = self._refiner.refine(cloud.xyz.reshape(msg.height, msg.width, 3), nominal, joints[0])
            if fit.accepted:
                self._corrections[frame] = fit.correction
                self.get_logger().info(f"{topic}: extrinsic refined from the robot by {fit.translation * 1000:.1f} mm / "
                                       f"{fit.rotation_deg:.2f} deg (fitness {fit.fitness:.2f}, RMSE {fit.rmse * 1000:.1f} mm)",
                                       throttle_duration_sec=60.0)
            else:
                self._report(f"refine:{topic}", f"{topic}: extrinsic refinement refused: {fit.reason}; the last one kept")
            out.append(CameraCloud(cloud.xyz, cloud.rgb, self._corrections.get(frame, np.eye(4)) @ nominal))
        return out

    def _process(self, msgs: list[PointCloud2]) -> None:
        clouds = [self._decode(topic, msg) for topic, msg in zip(self._topics, msgs)]
        if any(c is None for c in clouds):
            return
        if self._refiner is not None:
            clouds = self._refine(msgs, clouds)
        try:
            fused = self._perception.fuse(clouds)
        except EmptyObservationError as exc:
            self._report("workspace", str(exc))
            return
        stamp = max((m.header.stamp for m in msgs), key=stamp_ns)
        # The unfiltered cloud goes out as soon as clouds arrive: it needs no joint state.
        if not self._remove_robot_fused and self._fused_pub.get_subscription_count():
            self._fused_pub.publish(to_msg(fused.xyz, fused.rgb, self._world, stamp))
        if self._needs_joints and not self._pose_robot_at(msgs):
            return
        without_robot = self._perception.without_robot(fused) if self._needs_joints else fused
        if self._remove_robot_fused and self._fused_pub.get_subscription_count():
            self._fused_pub.publish(to_msg(without_robot.xyz, without_robot.rgb, self._world, stamp))
        views = self._perception.render(without_robot if self._perception.config.remove_robot_views else fused)
        self._views_pub.publish(self._views_msg(views, stamp, self._digest))
        if self._alternate_pub is not None:
            other = self._perception.render(without_robot if self._alternate.remove_robot_views else fused)
            self._alternate_pub.publish(self._views_msg(other, stamp, self._alternate.digest()))
        if self._preview_pub.get_subscription_count() and self._has_preview:
            self._preview_pub.publish(self._preview_msg(views, stamp))

    def _joint_positions(self, stamps: list[int], consequence: str) -> list[dict[str, float]] | None:
        """The joint positions at each of the sorted ``stamps``; None (reason and ``consequence`` logged) when
        they are unknown."""
        deadline = time.monotonic() + self._joint_wait
        try:
            with self._joint_arrived:
                while not self._joint_history.covers(stamps[-1]) and (left := deadline - time.monotonic()) > 0:
                    self._joint_arrived.wait(left)  # the JointState just after the cloud is usually on its way
                return [self._joint_history.at(stamp) for stamp in stamps]
        except JointStateUnavailable as exc:
            self._report("joint_states:unknown", f"{consequence}: {exc}")
            return None

    def _pose_robot_at(self, msgs: list[PointCloud2]) -> bool:
        """Pose the self-filter's robot at each distinct cloud stamp of the set; False (reason
        logged) when the joint states there are unknown."""
        stamps = sorted({stamp_ns(m.header.stamp) for m in msgs})
        configurations = self._joint_positions(stamps, f"{', '.join(self._waiting)} wait: the robot cannot be removed")
        if configurations is None:
            return False
        self._perception.self_filter.set_configurations(configurations)
        return True

    def _views_msg(self, views: np.ndarray, stamp, digest: str) -> OrthoViews:
        config = self._perception.config
        msg = OrthoViews()
        msg.header.stamp = stamp
        msg.header.frame_id = self._world
        msg.height, msg.width = int(views.shape[2]), int(views.shape[3])
        msg.views = list(VIEWS)
        msg.channels = list(config.channels)
        data = array.array("f")
        data.frombytes(np.ascontiguousarray(views, dtype=np.float32).tobytes())
        msg.data = data
        msg.center.x, msg.center.y, msg.center.z = config.center
        msg.half_extent = float(config.half_extent)
        msg.config_digest = digest
        return msg

    def _preview_msg(self, views: np.ndarray, stamp) -> Image:
        mosaic = rgb_mosaic(views, self._perception.config.channels)
        msg = Image()
        msg.header.stamp = stamp
        msg.header.frame_id = self._world
        msg.height, msg.width = mosaic.shape[:2]
        msg.encoding = "rgb8"
        msg.step = 3 * mosaic.shape[1]
        msg.data = mosaic.tobytes()
        return msg


def main(args: list[str] | None = None) -> int:
    keep_freed_memory()  # per-set buffers stay in the heap instead of being faulted in again (2-4 ms a set)
    return spin(FusionNode, "fusion_node", args)


if __name__ == "__main__":
    raise SystemExit(main())
