"""episode_runner: runs manipulation episodes against the node graph (DESIGN.md, "The sim loop").

One episode: /reset_scene -> wait for a /fused_points cloud newer than the reset -> choose the
four keyposes -> /execute_keypose for INIT, REACH, GRASP, MANIPULATE in order -> success if any
object DoF moved by more than 30 % of its range (/object_state against the limits ResetScene
returned). START and END go out on /episode (transient local, so a late bag recorder gets them).

Keyposes come from the heuristic grasp sampler of the data-collection pipeline
(actaim2.data.grasp_sampler), which sees only the fused, robot-filtered cloud: no privileged
state. It is the non-learned baseline; the learned mode selector and action predictor slot in
at the same place ("choose the four keyposes") through /sample_mode and /predict_keypose.

The runner exits when its episodes are done and logs a summary; Ctrl-C cancels the running
goal first, so the arm is not left moving.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np
import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.action import ActionClient
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.time import Time
from sensor_msgs.msg import JointState, PointCloud2

from actaim2.data.grasp_sampler import HeuristicGraspSampler
from actaim2.data.object_cloud import CloudConfig, ObjectCloud, remove_support
from actaim2.runtime import apply_ros_defaults
from actaim2.sim.success import SUCCESS_FRACTION, moved_fraction
from actaim2_msgs.action import ExecuteKeypose
from actaim2_msgs.msg import EpisodeEvent, Keypose
from actaim2_msgs.srv import ResetScene
from actaim2_perception.pointcloud2 import from_msg

EPISODE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# s (wall): how long the runner waits, before it exits, for /episode subscribers to acknowledge the
# last events (transient local keeps them only while the runner lives: an END sent just before
# exit was lost otherwise)
EVENT_ACK_TIMEOUT = 2.0

PARAMETERS: dict[str, tuple[object, str]] = {
    "episodes": (3, "number of episodes to run, then exit"),
    "category": ("storage_furniture", "object category passed to /reset_scene"),
    "instance": (-1, "object instance (-1: drawn from the episode's seed)"),
    "seed": (0, "seed of episode 0; episode k uses seed + k (scene and keypose sampling)"),
    "dof_fraction": (0.5, "initial state of every object DoF as a fraction of its range"),
    "velocity_scaling": (0.5, "ExecuteKeypose velocity_scaling (0, 1]"),
    "fused_points_topic": ("/fused_points", "fused, robot-filtered cloud in `world`"),
    "workspace_center": ([0.75, 0.0, 0.4], "m, world: the cube the object cloud is taken from"),
    "workspace_half_extent": (0.6, "m"),
    "samples_per_episode": (20, "heuristic grasp draws before the episode is declared unsampleable"),
    "cloud_timeout": (30.0, "s (wall) to wait for a cloud newer than the reset"),
    "service_timeout": (30.0, "s (wall) to wait for /reset_scene and for servers to appear"),
    "goal_timeout": (120.0, "s (wall) for one ExecuteKeypose goal"),
    "settle_time": (1.0, "s (sim) after the last keypose before the object state is read"),
}


@dataclass
class EpisodeResult:
    episode: int
    object_id: str
    success: bool
    moved: float  # largest |DoF change| as a fraction of its range
    note: str


class EpisodeRunner(Node):
    """Drives reset -> observe -> keyposes -> execute -> judge, one episode after another."""

    def __init__(self) -> None:
        # Stamps of clouds and object states are sim time (/clock): the runner only makes sense on it.
        super().__init__("episode_runner", parameter_overrides=[Parameter("use_sim_time", value=True)])
        for name, (default, description) in PARAMETERS.items():
            self.declare_parameter(name, default, ParameterDescriptor(description=description))
        self.p = {name: self.get_parameter(name).value for name in PARAMETERS}
        self._reset_client = self.create_client(ResetScene, "/reset_scene")
        self._execute_client = ActionClient(self, ExecuteKeypose, "/execute_keypose")
        self._episode_pub = self.create_publisher(EpisodeEvent, "/episode", EPISODE_QOS)
        self._lock = threading.Lock()
        self._cloud: PointCloud2 | None = None
        self._object_state: JointState | None = None
        self.create_subscription(PointCloud2, self.p["fused_points_topic"], self._on_cloud, qos_profile_sensor_data)
        self.create_subscription(JointState, "/object_state", self._on_object_state, 10)
        center = tuple(float(c) for c in self.p["workspace_center"])
        self._sampler = HeuristicGraspSampler(CloudConfig(center=center, half_extent=float(self.p["workspace_half_extent"])))
        self._active_goal = None
        self.stopping = threading.Event()

    def _on_cloud(self, msg: PointCloud2) -> None:
        with self._lock:
            self._cloud = msg

    def _on_object_state(self, msg: JointState) -> None:
        with self._lock:
            self._object_state = msg

    # -- waiting on ROS from the runner thread ---------------------------------------------
    def _wait_future(self, future, timeout: float, what: str):
        done = threading.Event()
        future.add_done_callback(lambda _: done.set())
        if not done.wait(timeout) or self.stopping.is_set():
            raise RuntimeError(f"{what}: no answer within {timeout:.0f} s" if not self.stopping.is_set() else "stopped")
        return future.result()

    def _wait_for(self, predicate, timeout: float, what: str):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not self.stopping.is_set():
            value = predicate()
            if value is not None:
                return value
            time.sleep(0.02)
        raise RuntimeError(f"{what} within {timeout:.0f} s" if not self.stopping.is_set() else "stopped")

    def _latest_after(self, attribute: str, stamp: Time) -> object | None:
        with self._lock:
            msg = getattr(self, attribute)
        return msg if msg is not None and Time.from_msg(msg.header.stamp) > stamp else None

    # -- one episode -------------------------------------------------------------------------
    def _publish_event(self, episode: int, event: int, object_id: str, success: bool = False, note: str = "") -> None:
        msg = EpisodeEvent(episode=episode, event=event, object_id=object_id, success=success, note=note)
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = "world"
        self._episode_pub.publish(msg)

    def _reset(self, seed: int) -> ResetScene.Response:
        request = ResetScene.Request(category=self.p["category"], instance=int(self.p["instance"]), seed=seed,
                                     dof_fraction=float(self.p["dof_fraction"]))
        response = self._wait_future(self._reset_client.call_async(request), self.p["service_timeout"], "/reset_scene")
        if not response.success:
            raise RuntimeError(f"/reset_scene refused: {response.message}")
        return response

    def _object_cloud(self, msg: PointCloud2, rng: np.random.Generator) -> ObjectCloud:
        decoded = from_msg(msg)
        valid = np.all(np.isfinite(decoded.xyz), axis=1)
        points = decoded.xyz[valid].astype(np.float64)
        colors = decoded.rgb[valid] if decoded.rgb is not None else np.zeros((len(points), 3), np.uint8)
        keep = remove_support(points, self._sampler.cloud_config, rng)
        return ObjectCloud(points[keep], colors[keep])

    def _execute(self, keypose: Keypose) -> ExecuteKeypose.Result:
        goal = ExecuteKeypose.Goal(keypose=keypose, velocity_scaling=float(self.p["velocity_scaling"]))
        handle = self._wait_future(self._execute_client.send_goal_async(goal), self.p["service_timeout"], "/execute_keypose goal")
        if not handle.accepted:
            raise RuntimeError("/execute_keypose rejected the goal")
        self._active_goal = handle
        try:
            return self._wait_future(handle.get_result_async(), self.p["goal_timeout"], "/execute_keypose result").result
        finally:
            self._active_goal = None

    def run_episode(self, episode: int) -> EpisodeResult:
        seed = int(self.p["seed"]) + episode
        rng = np.random.default_rng(seed)
        reset = self._reset(seed)
        object_id = reset.object_id
        self._publish_event(episode, EpisodeEvent.START, object_id, note="heuristic grasp sampler")
        # The first state and cloud stamped after the reset answered belong to the new scene.
        reset_stamp = self.get_clock().now()
        state0 = self._wait_for(lambda: self._latest_after("_object_state", reset_stamp), self.p["cloud_timeout"], "no /object_state after the reset")
        cloud = self._wait_for(lambda: self._latest_after("_cloud", reset_stamp), self.p["cloud_timeout"],
                               f"no {self.p['fused_points_topic']} cloud newer than the reset")
        object_cloud = self._object_cloud(cloud, rng)
        action = None
        for index in range(int(self.p["samples_per_episode"])):
            action = self._sampler.sample(object_cloud, rng, index)
            if action is not None:
                break
        if action is None:
            return self._finish(episode, object_id, False, 0.0, f"no grasp found on {len(object_cloud.points)} object points")
        note = ""
        for kp in action.keyposes():
            msg = Keypose(gripper_closed=bool(kp.gripper_closed), phase=int(kp.phase))
            msg.header.frame_id = "world"
            msg.header.stamp = cloud.header.stamp
            msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(v) for v in kp.position)
            msg.pose.orientation.x, msg.pose.orientation.y, msg.pose.orientation.z, msg.pose.orientation.w = (float(v) for v in kp.quat_xyzw)
            result = self._execute(msg)
            if not result.success:
                # The object decides success, not the arm: a drawer at its end stop keeps the hand
                # from p2, and a REACH that bumps a door may already have opened it.
                note = f"stopped at phase {kp.phase}: {result.message}"
                break
        settle_until = self.get_clock().now() + Duration(seconds=float(self.p["settle_time"]))
        self._wait_for(lambda: self._latest_after("_object_state", settle_until), self.p["cloud_timeout"], "no /object_state after the motion")
        moved = self._moved(state0, reset)
        return self._finish(episode, object_id, moved > SUCCESS_FRACTION, moved, note)

    def _moved(self, state0: JointState, reset: ResetScene.Response) -> float:
        with self._lock:
            state = self._object_state
        index = {name: i for i, name in enumerate(state.name)}
        order = [index[name] for name in reset.dof_names]
        fraction = moved_fraction(np.asarray(state0.position)[order], np.asarray(state.position)[order], reset.dof_lower, reset.dof_upper)
        return float(np.max(np.abs(fraction), initial=0.0))

    def _finish(self, episode: int, object_id: str, success: bool, moved: float, note: str) -> EpisodeResult:
        self._publish_event(episode, EpisodeEvent.END, object_id, success, note)
        self.get_logger().info(f"episode {episode} {object_id}: {'SUCCESS' if success else 'failure'} "
                               f"(largest DoF change {100 * moved:.0f}% of its range){': ' + note if note else ''}")
        return EpisodeResult(episode, object_id, success, moved, note)

    def run(self) -> list[EpisodeResult]:
        """All episodes; an episode that cannot run (a server missing) is a failure with the reason."""
        for client, name in ((self._reset_client, "/reset_scene"),):
            if not client.wait_for_service(timeout_sec=self.p["service_timeout"]):
                raise RuntimeError(f"{name} is not available (is sim_node running?)")
        if not self._execute_client.wait_for_server(timeout_sec=self.p["service_timeout"]):
            raise RuntimeError("/execute_keypose is not available (is control_node running?)")
        self.get_logger().info("keyposes from the heuristic grasp sampler on the fused cloud (no privileged state)")
        results = []
        for episode in range(int(self.p["episodes"])):
            if self.stopping.is_set():
                break
            try:
                results.append(self.run_episode(episode))
            except RuntimeError as exc:
                if self.stopping.is_set():
                    break
                results.append(self._finish(episode, "", False, 0.0, str(exc)))
        successes = sum(r.success for r in results)
        self.get_logger().info(f"{successes}/{len(results)} episodes succeeded")
        self._episode_pub.wait_for_all_acked(Duration(seconds=EVENT_ACK_TIMEOUT))
        return results

    def stop(self) -> None:
        """Ctrl-C: stop after cancelling the running goal so that the arm is not left moving."""
        self.stopping.set()
        handle = self._active_goal
        if handle is not None:
            done = threading.Event()
            handle.cancel_goal_async().add_done_callback(lambda _: done.set())
            done.wait(2.0)


def main(args: list[str] | None = None) -> int:
    apply_ros_defaults()
    rclpy.init(args=args)
    node = EpisodeRunner()
    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    code = 0
    try:
        results = node.run()
        code = 0 if results else 1
    except RuntimeError as exc:
        node.get_logger().error(str(exc))
        code = 1
    except (KeyboardInterrupt, ExternalShutdownException):
        node.stop()
    finally:
        executor.shutdown()
        spinner.join()  # out of rcl before the node goes: a thread left inside it aborted the process at exit
        node.destroy_node()
        rclpy.try_shutdown()
    return code
