"""actaim2's interfaces between two real rclpy processes over DDS on loopback.

The peer (interface_peer.py, its own process with this run's ROS_DOMAIN_ID) serves the services
and the action and echoes the topics; this process is the client, publisher and subscriber. Every
wait is for discovery or for data (wait_for_service, wait_for_server, matched endpoints, an
arriving message), each with a timeout.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import pytest

from harness import REPO, matched, wait_for

PEER = Path(__file__).with_name("interface_peer.py")
DISCOVERY_TIMEOUT = 15.0
CALL_TIMEOUT = 10.0


@pytest.fixture(scope="module")
def peer(tmp_path_factory) -> Iterator[subprocess.Popen]:
    """interface_peer.py in its own process; Ctrl-C at the end must stop it cleanly (exit 0)."""
    log_path = tmp_path_factory.mktemp("peer") / "interface_peer.log"
    with open(log_path, "w") as log:
        proc = subprocess.Popen([sys.executable, str(PEER)], stdout=log, stderr=subprocess.STDOUT,
                                env=os.environ.copy(), start_new_session=True)
        yield proc
        os.killpg(proc.pid, signal.SIGINT)
        try:
            returncode = proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            returncode = proc.wait()
    assert returncode == 0, f"peer exited with {returncode}:\n{log_path.read_text()[-3000:]}"


def _result(future, timeout: float = CALL_TIMEOUT) -> Any:
    """The result of an rclpy future completed by the ros_node fixture's executor thread."""
    done = threading.Event()
    future.add_done_callback(lambda _f: done.set())
    assert done.wait(timeout), "no answer from the peer process"
    return future.result()


def _call(node, srv_type, name: str, request) -> Any:
    client = node.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=DISCOVERY_TIMEOUT), f"{name} not discovered"
    return _result(client.call_async(request))


# --- (a) services -------------------------------------------------------------------------

def test_sample_mode_across_processes(ros_node, peer) -> None:
    from actaim2_msgs.srv import SampleMode

    response = _call(ros_node, SampleMode, "/sample_mode", SampleMode.Request(cluster=2, seed=7))
    assert response.success and response.message == ""
    assert response.cluster == 2
    assert list(response.embedding) == [2.0, 7.0, 0.5]
    assert list(response.cluster_probabilities) == [0.25, 0.25, 0.5]
    assert response.observation_stamp.sec == 7

    sampled = _call(ros_node, SampleMode, "/sample_mode", SampleMode.Request(cluster=-1, seed=5))
    assert sampled.success and sampled.cluster == 5 % 3


def test_sample_mode_bad_request_gets_a_reason(ros_node, peer) -> None:
    from actaim2_msgs.srv import SampleMode

    response = _call(ros_node, SampleMode, "/sample_mode", SampleMode.Request(cluster=-5, seed=1))
    assert not response.success
    assert "cluster" in response.message and "-5" in response.message
    assert peer.poll() is None, "the server must keep running after a bad request"


def test_predict_keypose_across_processes(ros_node, peer) -> None:
    from actaim2_msgs.msg import Keypose
    from actaim2_msgs.srv import PredictKeypose
    from builtin_interfaces.msg import Time

    request = PredictKeypose.Request(embedding=[0.25, 0.5], phase=Keypose.PHASE_GRASP, gripper_closed=True,
                                     not_before=Time(sec=12, nanosec=345))
    response = _call(ros_node, PredictKeypose, "/predict_keypose", request)
    assert response.success
    keypose = response.keypose
    assert keypose.header.frame_id == "world"
    assert (keypose.header.stamp.sec, keypose.header.stamp.nanosec) == (12, 345)
    assert (keypose.pose.position.x, keypose.pose.position.z) == (0.75, float(Keypose.PHASE_GRASP))
    assert keypose.pose.orientation.w == 1.0
    assert keypose.gripper_closed and keypose.phase == Keypose.PHASE_GRASP
    assert response.confidence == pytest.approx(0.75)


@pytest.mark.parametrize(("embedding", "phase", "reason"), [([], 0, "embedding is empty"), ([1.0], 7, "unknown phase 7")], ids=["empty_embedding", "unknown_phase"])
def test_predict_keypose_bad_request_gets_a_reason(ros_node, peer, embedding, phase, reason) -> None:
    from actaim2_msgs.srv import PredictKeypose

    response = _call(ros_node, PredictKeypose, "/predict_keypose", PredictKeypose.Request(embedding=embedding, phase=phase))
    assert not response.success and reason in response.message


# --- (b) topics ---------------------------------------------------------------------------

def _round_trip(node, msg_type, topic: str, qos, make: Callable[[int], Any]) -> tuple[Any, Any]:
    """Publish ``make(i)`` on ``topic`` until the peer's echo of one arrives; (sent, echoed).

    Each message carries its number in header.stamp.sec, so the echo is matched to what was sent
    (sensor-data QoS is best effort: a message may be dropped, the next one is sent then).
    """
    echoes: list = []
    arrived = threading.Event()

    def on_echo(msg) -> None:
        echoes.append(msg)
        arrived.set()

    publisher = node.create_publisher(msg_type, topic, qos)
    node.create_subscription(msg_type, f"{topic}/echo", on_echo, qos)
    assert wait_for(lambda: publisher.get_subscription_count() > 0 and node.count_publishers(f"{topic}/echo") > 0,
                    timeout=DISCOVERY_TIMEOUT), f"peer endpoints of {topic} not discovered"
    sent = {}
    for i in range(50):
        sent[i] = make(i)
        publisher.publish(sent[i])
        if arrived.wait(timeout=0.2):
            break
    assert echoes, f"no echo on {topic}/echo"
    echoed = echoes[0]
    return sent[echoed.header.stamp.sec], echoed


def test_ortho_views_round_trip_exactly(ros_node, peer) -> None:
    from actaim2_msgs.msg import OrthoViews
    from rclpy.qos import QoSProfile

    rng = np.random.default_rng(0)
    views, channels, size = ["top", "front", "back", "left", "right"], ["r", "g", "b", "x", "y", "z", "depth"], 16
    data = rng.standard_normal(len(views) * len(channels) * size * size).astype(np.float32)
    data[::97] = np.nan  # empty pixels survive as NaN

    def make(i: int) -> OrthoViews:
        msg = OrthoViews(height=size, width=size, views=views, channels=channels, data=data, half_extent=0.6)
        msg.header.frame_id, msg.header.stamp.sec = "world", i
        msg.center.x, msg.center.y, msg.center.z = 0.5, -0.25, 0.3
        return msg

    sent, echoed = _round_trip(ros_node, OrthoViews, "/ortho_views", QoSProfile(depth=1), make)
    assert echoed.header.frame_id == "world"
    assert (echoed.height, echoed.width) == (size, size)
    assert list(echoed.views) == views and list(echoed.channels) == channels
    assert np.asarray(echoed.data, dtype=np.float32).tobytes() == data.tobytes()
    assert (echoed.center.x, echoed.center.y, echoed.center.z) == (0.5, -0.25, 0.3)
    assert echoed.half_extent == pytest.approx(0.6)
    assert sent.header.stamp.sec == echoed.header.stamp.sec


def _organized_cloud(height: int, width: int, rng: np.random.Generator) -> tuple[np.ndarray, list]:
    """Azure-Kinect-driver layout: x, y, z float32 at 0, 4, 8; rgb float32 at 16; 32-byte points."""
    from sensor_msgs.msg import PointField

    dtype = np.dtype({"names": ["x", "y", "z", "rgb"], "formats": ["<f4"] * 4, "offsets": [0, 4, 8, 16], "itemsize": 32})
    points = np.zeros(height * width, dtype=dtype)
    for axis in ("x", "y", "z"):
        points[axis] = rng.uniform(-1.0, 2.0, points.size)
    points["rgb"] = rng.integers(0, 2**24, points.size).astype(np.uint32).view(np.float32)
    points["x"][::13] = points["y"][::13] = points["z"][::13] = np.nan  # no return
    fields = [PointField(name=name, offset=offset, datatype=PointField.FLOAT32, count=1)
              for name, offset in (("x", 0), ("y", 4), ("z", 8), ("rgb", 16))]
    return points, fields


def test_point_cloud_round_trips_exactly_with_sensor_qos(ros_node, peer) -> None:
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import PointCloud2

    height, width = 48, 64
    points, fields = _organized_cloud(height, width, np.random.default_rng(1))
    payload = points.tobytes()

    def make(i: int) -> PointCloud2:
        msg = PointCloud2(height=height, width=width, fields=fields, is_bigendian=False, point_step=32,
                          row_step=32 * width, data=payload, is_dense=False)
        msg.header.frame_id, msg.header.stamp.sec = "depth_camera_link", i
        return msg

    sent, echoed = _round_trip(ros_node, PointCloud2, "/cloud", qos_profile_sensor_data, make)
    assert echoed.header.frame_id == "depth_camera_link"
    assert (echoed.height, echoed.width, echoed.point_step, echoed.row_step) == (height, width, 32, 32 * width)
    assert [(f.name, f.offset, f.datatype, f.count) for f in echoed.fields] == [(f.name, f.offset, f.datatype, f.count) for f in fields]
    assert not echoed.is_dense and not echoed.is_bigendian
    assert bytes(echoed.data) == payload


# --- (c) action ---------------------------------------------------------------------------

def _action_client(node):
    from actaim2_msgs.action import ExecuteKeypose

    from actaim2_ros.action_client import LockedActionClient

    client = LockedActionClient(node, ExecuteKeypose, "/execute_keypose")
    assert client.wait_for_server(timeout_sec=DISCOVERY_TIMEOUT), "/execute_keypose not discovered"
    return client


def _goal(velocity_scaling: float, phase: int):
    from actaim2_msgs.action import ExecuteKeypose

    goal = ExecuteKeypose.Goal(velocity_scaling=velocity_scaling)
    goal.keypose.header.frame_id = "world"
    goal.keypose.pose.orientation.w = 1.0
    goal.keypose.phase = phase
    return goal


def test_execute_keypose_goal_feedback_result(ros_node, peer) -> None:
    from actaim2_msgs.action import ExecuteKeypose
    from actaim2_msgs.msg import Keypose
    from action_msgs.msg import GoalStatus

    client = _action_client(ros_node)
    # Feedback is a topic and the result a service answer, and rclpy's ActionClient drops a goal's
    # feedback callback once its result arrives: feedback taken after the result never reaches the
    # callback (a loaded machine did this: 0.1-0.4 arrived, 0.5-1.0 after the result). The whole
    # sequence is read from the feedback topic itself, which a result does not close.
    published: list = []
    topic = ros_node.create_subscription(ExecuteKeypose.Impl.FeedbackMessage, "/execute_keypose/_action/feedback",
                                         published.append, 10)
    assert wait_for(matched(topic), DISCOVERY_TIMEOUT), "the feedback topic did not match the action server"
    feedback: list = []
    goal_handle = _result(client.send_goal_async(_goal(1.0, Keypose.PHASE_REACH), feedback_callback=lambda f: feedback.append(f.feedback)))
    assert goal_handle.accepted
    outcome = _result(goal_handle.get_result_async())
    assert outcome.status == GoalStatus.STATUS_SUCCEEDED
    assert outcome.result.success and outcome.result.message == ""
    def ours() -> list:
        return [m.feedback for m in published if bytes(m.goal_id.uuid) == bytes(goal_handle.goal_id.uuid)]

    wait_for(lambda: bool(ours()) and ours()[-1].progress == pytest.approx(1.0), CALL_TIMEOUT)
    ros_node.destroy_subscription(topic)
    received = ours()
    assert feedback, "no feedback reached the goal's callback"
    progress = [f.progress for f in received]
    assert progress == sorted(progress) and progress[-1] == pytest.approx(1.0)
    assert {f.phase for f in received} == {Keypose.PHASE_REACH}


def test_execute_keypose_cancel(ros_node, peer) -> None:
    from action_msgs.msg import GoalStatus

    client = _action_client(ros_node)
    first_feedback = threading.Event()
    goal_handle = _result(client.send_goal_async(_goal(0.1, 0), feedback_callback=lambda _f: first_feedback.set()))
    assert goal_handle.accepted
    assert first_feedback.wait(CALL_TIMEOUT), "no feedback before cancelling"
    cancel = _result(goal_handle.cancel_goal_async())
    assert len(cancel.goals_canceling) == 1
    outcome = _result(goal_handle.get_result_async())
    assert outcome.status == GoalStatus.STATUS_CANCELED
    assert not outcome.result.success and outcome.result.message == "cancelled"


def test_execute_keypose_bad_goal_is_aborted_with_a_reason(ros_node, peer) -> None:
    from action_msgs.msg import GoalStatus

    client = _action_client(ros_node)
    goal_handle = _result(client.send_goal_async(_goal(0.0, 0)))
    outcome = _result(goal_handle.get_result_async())
    assert outcome.status == GoalStatus.STATUS_ABORTED
    assert not outcome.result.success and "velocity_scaling" in outcome.result.message


# --- (d) ros2 run -------------------------------------------------------------------------

ROS2_SHIM = REPO / "tools" / "bin" / "ros2"


def test_ros2_run_starts_a_package_executable(ros_node, start_node, tmp_path) -> None:
    """`ros2 run actaim2_perception calibration_publisher --ros-args --params-file ...` publishes."""
    import yaml
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from tf2_msgs.msg import TFMessage

    calibration = tmp_path / "calibration.yaml"
    calibration.write_text(yaml.safe_dump({"parent_frame": "world", "transforms": {
        "camera_base": [[0, -1, 0, 0.5], [1, 0, 0, -0.2], [0, 0, 1, 1.1], [0, 0, 0, 1]]}}))
    received: list[TFMessage] = []
    latched = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
    ros_node.create_subscription(TFMessage, "/tf_static", received.append, latched)

    node = start_node("actaim2_perception", "calibration_publisher", params={"calibration_file": str(calibration)})
    assert wait_for(lambda: bool(received) or not node.alive(), timeout=DISCOVERY_TIMEOUT), "no /tf_static"
    assert received, f"calibration_publisher exited:\n{node.output()}"
    (transform,) = received[0].transforms
    assert (transform.header.frame_id, transform.child_frame_id) == ("world", "camera_base")
    t, q = transform.transform.translation, transform.transform.rotation
    assert (t.x, t.y, t.z) == pytest.approx((0.5, -0.2, 1.1))
    assert (q.x, q.y, q.z, q.w) == pytest.approx((0.0, 0.0, np.sqrt(0.5), np.sqrt(0.5)))  # +90 deg about z
    assert node.stop() == 0, node.output()


def test_ros2_run_unknown_package_is_a_clear_error() -> None:
    done = subprocess.run([str(ROS2_SHIM), "run", "no_such_package", "talker"], capture_output=True, text=True, timeout=30)
    assert done.returncode != 0
    assert "Package 'no_such_package' not found" in done.stderr


def test_ros2_run_unknown_executable_lists_the_available_ones() -> None:
    done = subprocess.run([str(ROS2_SHIM), "run", "actaim2_perception", "no_such_executable"],
                          capture_output=True, text=True, timeout=30)
    assert done.returncode != 0
    assert "No executable found: 'no_such_executable' in package 'actaim2_perception'" in done.stderr
    assert "calibration_publisher" in done.stderr
