"""control_node over rclpy against the real sim_node: keyposes, a drawer pull, cancel, fallbacks.

The drawer's handle pose is privileged information read from an in-process SimEnv built with
the sim node's scene parameters (same category, instance and seed: same placement).
"""
from __future__ import annotations

import re
import threading
import time

import numpy as np
import pytest

from actaim2.control.model import RobotModel
from actaim2.geometry import matrix_to_pose, rotation_angle
from actaim2.robots import load_robot_spec
from harness import matched, wait_for

SCENE = {"category": "table", "instance": 0, "seed": 0}
SIM_PARAMS = {"robot": "panda", "camera_rate": 0.0, "render_path": "raycast", **SCENE}
DOWN_QUAT = [1.0, 0.0, 0.0, 0.0]  # tcp pointing down (x, y, z, w)


@pytest.fixture(scope="module")
def panda() -> RobotModel:
    return RobotModel(load_robot_spec("panda"))


@pytest.fixture(scope="module")
def drawer() -> dict:
    """Grasp pose of the drawer handle, its opening direction and the DoF's range."""
    from actaim2.sim.env import SimEnv

    env = SimEnv("panda", cameras=None)
    info = env.reset(SCENE["category"], instance=SCENE["instance"], seed=SCENE["seed"])
    handle = env.object.handles[0]
    joint = env.object.joints[env.object.dof_index(handle.joint)]
    T = env.object.link(handle.link).entity_pose.to_transformation_matrix() @ handle.tcp_in_link()
    i = info.dof_names.index(handle.joint)
    return {"T": T, "opening": joint.get_global_pose().to_transformation_matrix()[:3, 0], "joint": handle.joint,
            "range": float(info.dof_upper[i] - info.dof_lower[i])}


class Recorder:
    """Latest and timed /joint_states, /object_state and /keypose seen by the test node."""

    def __init__(self, node) -> None:
        from actaim2_msgs.msg import Keypose
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        self.lock = threading.Lock()
        # (monotonic time of receipt, positions, velocities, header stamp in sim seconds)
        self.joints: list[tuple[float, dict, dict, float]] = []
        self.object: dict[str, float] = {}
        self.keyposes = []
        node.create_subscription(JointState, "/joint_states", self._on_joints, 50)
        node.create_subscription(JointState, "/object_state", lambda m: self.object.update(zip(m.name, m.position)), 10)
        self.keypose_sub = node.create_subscription(Keypose, "/keypose", self.keyposes.append,
                                                    QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))

    def _on_joints(self, msg) -> None:
        with self.lock:
            stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            self.joints.append((time.monotonic(), dict(zip(msg.name, msg.position)), dict(zip(msg.name, msg.velocity)), stamp))

    def arm(self, names, since: float = -np.inf, until: float = np.inf, sim_time: bool = False):
        """(times, positions, velocities) of the arm joints received in [since, until]: times of receipt
        (monotonic), or with ``sim_time`` the messages' stamps, which a loaded machine cannot delay."""
        with self.lock:
            rows = [(s if sim_time else t, p, v) for t, p, v, s in self.joints]
        rows = [row for row in rows if since <= row[0] <= until]
        return (np.array([t for t, _, _ in rows]), np.array([[p[n] for n in names] for _, p, _ in rows]),
                np.array([[v[n] for n in names] for _, _, v in rows]))


class KeyposeClient:
    def __init__(self, node) -> None:
        from actaim2_msgs.action import ExecuteKeypose

        from actaim2_ros.action_client import LockedActionClient

        self.Action = ExecuteKeypose
        self.client = LockedActionClient(node, ExecuteKeypose, "/execute_keypose")
        self.feedback = []

    def goal(self, phase, position, quat_xyzw, closed, scaling=0.0, frame="world"):
        goal = self.Action.Goal(velocity_scaling=float(scaling))
        k = goal.keypose
        k.header.frame_id = frame
        k.phase, k.gripper_closed = phase, closed
        k.pose.position.x, k.pose.position.y, k.pose.position.z = (float(v) for v in position)
        o = k.pose.orientation
        o.x, o.y, o.z, o.w = (float(v) for v in quat_xyzw)
        return goal

    def send(self, goal, timeout: float = 60.0, on_feedback=None):
        """Send and return the goal handle."""
        self.feedback = []

        def keep(msg):
            self.feedback.append((time.monotonic(), msg.feedback))
            if on_feedback is not None:
                on_feedback(msg.feedback)

        sent = self.client.send_goal_async(goal, feedback_callback=keep)
        assert wait_for(sent.done, 10.0) and sent.result().accepted
        return sent.result()

    def result(self, handle, timeout: float = 60.0):
        future = handle.get_result_async()
        assert wait_for(future.done, timeout), "no result"
        return future.result().status, future.result().result

    def execute(self, goal, timeout: float = 60.0):
        return self.result(self.send(goal), timeout)


def tcp_error(panda: RobotModel, recorder: Recorder, position, quat_xyzw, tolerance=(0.005, np.radians(3.0))) -> tuple[float, float]:
    """tcp error of the latest /joint_states; this process may be behind the nodes on a busy
    machine, so it waits (up to 3 s) for its /joint_states to show the settled arm."""
    from actaim2.geometry import pose_to_matrix

    goal = pose_to_matrix(position, quat_xyzw)

    def error() -> tuple[float, float]:
        _, q, _ = recorder.arm(panda.joint_names)
        T = panda.fk(q[-1])
        return float(np.linalg.norm(T[:3, 3] - goal[:3, 3])), rotation_angle(T[:3, :3], goal[:3, :3])

    wait_for(lambda: error()[0] <= tolerance[0] and error()[1] <= tolerance[1], 3.0)
    return error()


def start_cell(start_node, ros_node, control_params: dict | None = None):
    start_node("actaim2_sim", "sim_node", SIM_PARAMS)
    control = start_node("actaim2_control", "control_node", control_params or {})
    recorder, client = Recorder(ros_node), KeyposeClient(ros_node)
    assert client.client.wait_for_server(timeout_sec=30.0), control.output()
    assert wait_for(lambda: len(recorder.joints) > 5, 30.0), "no /joint_states from the sim"
    assert wait_for(matched(recorder.keypose_sub), 30.0), control.output()
    return recorder, client, control


def test_malformed_goals_are_rejected_with_a_message(start_node, ros_node):
    from action_msgs.msg import GoalStatus

    node = start_node("actaim2_control", "control_node", {"joint_states_wait": 0.5})
    client = KeyposeClient(ros_node)
    assert client.client.wait_for_server(timeout_sec=30.0), node.output()
    cases = [
        (client.goal(0, [0.4, float("nan"), 0.4], DOWN_QUAT, False), "not finite"),
        (client.goal(0, [0.4, 0.0, 0.4], [0.0, 0.0, 0.0, 0.5], False), "unit quaternion"),
        (client.goal(0, [0.4, 0.0, 0.4], DOWN_QUAT, False, frame="camera_link"), "frame 'camera_link'"),
        (client.goal(7, [0.4, 0.0, 0.4], DOWN_QUAT, False), "unknown phase 7"),
        (client.goal(0, [0.4, 0.0, 0.4], DOWN_QUAT, False, scaling=1.5), "velocity_scaling"),
        (with_alternative(client, client.goal(3, [0.4, 0.0, 0.4], DOWN_QUAT, False)), "alternatives[0] is phase 3"),
        (with_alternative(client, client.goal(0, [0.4, 0.0, 0.4], [0.0, 0.0, 0.0, 0.5], False)),
         "alternatives[0] orientation"),
        # well-formed, but there is no robot: nothing moves, the reason is given
        (client.goal(0, [0.4, 0.0, 0.4], DOWN_QUAT, False), "/joint_states"),
    ]
    for goal, expected in cases:
        status, result = client.execute(goal, timeout=20.0)
        assert status == GoalStatus.STATUS_ABORTED and not result.success
        assert expected in result.message and result.candidate == -1, result.message
    assert node.alive()


def with_alternative(client: KeyposeClient, alternative):
    """A well-formed INIT goal whose one fallback is ``alternative``'s keypose."""
    goal = client.goal(0, [0.4, 0.0, 0.4], DOWN_QUAT, False)
    goal.alternatives = [alternative.keypose]
    return goal


def test_four_phase_drawer_pull_through_the_sim(start_node, ros_node, panda, drawer):
    from action_msgs.msg import GoalStatus

    recorder, client, _ = start_cell(start_node, ros_node)
    assert wait_for(lambda: drawer["joint"] in recorder.object, 10.0)
    dof_before = recorder.object[drawer["joint"]]
    T = drawer["T"]
    p1, approach = T[:3, 3], T[:3, 2]
    p2 = p1 + 0.12 * drawer["opening"]
    _, quat = matrix_to_pose(T)
    phases = [(0, p1 - 0.12 * approach, False), (1, p1, False), (2, p1, True), (3, p2, True)]
    for phase, position, closed in phases:
        start = time.monotonic()
        status, result = client.execute(client.goal(phase, position, quat, closed))
        assert status == GoalStatus.STATUS_SUCCEEDED and result.success, result.message
        assert result.position_error <= 0.005 and result.orientation_error <= np.radians(3.0)
        # measured independently from /joint_states
        position_error, orientation_error = tcp_error(panda, recorder, position, quat)
        assert position_error <= 0.005 and orientation_error <= np.radians(3.0), (phase, position_error, orientation_error)
        # feedback is a topic, the result a service: feedback arriving after the result is
        # dropped by the client, so the final progress = 1 may be missing
        progress = [f.progress for _, f in client.feedback]
        assert progress and all(f.phase == phase for _, f in client.feedback)
        assert progress == sorted(progress), progress
        if phase == 3:  # the grasped drawer came along a straight line (then stayed at p2)
            _, q, _ = recorder.arm(panda.joint_names, since=start, until=time.monotonic())
            tcp = np.array([panda.fk(qi)[:3, 3] for qi in q])
            ab = p2 - p1
            s = np.clip((tcp - p1) @ ab / (ab @ ab), 0.0, 1.0)
            deviation = np.linalg.norm(tcp - (p1 + s[:, None] * ab), axis=1)
            assert len(q) > 20 and deviation.max() <= 0.002, deviation.max()
    moved = recorder.object[drawer["joint"]] - dof_before
    assert abs(moved) > 0.3 * drawer["range"], moved
    assert wait_for(lambda: len(recorder.keyposes) == 4, 5.0)
    assert [k.phase for k in recorder.keyposes] == [0, 1, 2, 3] and recorder.keyposes[1].header.frame_id == "world"


def test_cancel_stops_the_arm_within_half_a_second(start_node, ros_node, panda):
    from action_msgs.msg import GoalStatus

    recorder, client, _ = start_cell(start_node, ros_node)
    moving = threading.Event()
    # a long, slow joint-space move (about 10 s): home -> far to the left and down. Cancelled at a tenth
    # of it, so the cancel has seconds to arrive before the goal could succeed, however late this
    # process hears the feedback on a loaded machine (at scaling 0.15 a CI run saw the goal finish first).
    handle = client.send(client.goal(0, [0.3, 0.45, 0.25], DOWN_QUAT, False, scaling=0.06),
                         on_feedback=lambda f: f.progress > 0.1 and moving.set())
    assert moving.wait(30.0), "the arm never got under way"
    # Timed in sim time (the /joint_states stamps), from the state control_node braked from (named in
    # its result): the pytest process receives messages late and bunched on a loaded machine, so
    # neither its clock nor the newest stamp it holds when it sends the cancel says when the node
    # acted (a CI run measured 1.04 s from the latter). The delivery delay is reported, not bounded.
    sent_at = recorder.arm(panda.joint_names, sim_time=True)[0].max()
    handle.cancel_goal_async()
    status, result = client.result(handle, timeout=10.0)
    assert status == GoalStatus.STATUS_CANCELED and not result.success and "cancel" in result.message
    braked = re.search(r"braking from /joint_states stamped ([0-9.]+) s", result.message)
    assert braked, result.message
    braked_at = float(braked.group(1))
    # really moving when braked: the /joint_states it braked from (or those just before) show it
    assert wait_for(lambda: (np.abs(recorder.arm(panda.joint_names, since=braked_at - 0.25, until=braked_at,
                                                 sim_time=True)[2]) > 0.05).any(), 10.0), \
        "the arm was not moving when control_node braked"
    assert wait_for(lambda: recorder.arm(panda.joint_names, since=braked_at + 1.5, sim_time=True)[0].size > 0, 30.0), \
        "no /joint_states stamped 1.5 s after the brake reached the test"
    t, _, v = recorder.arm(panda.joint_names, since=braked_at, sim_time=True)
    still = np.all(np.abs(v) < 0.02, axis=1)
    moving_after = t[~still]
    stopped_at = moving_after.max() if len(moving_after) else braked_at
    assert stopped_at - braked_at <= 0.5, (stopped_at - braked_at, f"delivery: {braked_at - sent_at:.3f} s")
    after = t > braked_at + 0.5
    assert after.any() and still[after].all(), (t[-1] - braked_at, len(t))  # and stays still past the bound


def test_topic_fallback_and_cloud_obstacles(start_node, ros_node, panda):
    """Without the arm's action server the JTC topic moves the arm; with use_cloud a /fused_points
    plate over one target makes it unreachable, with the reason; a stamped keypose is planned around
    a cloud at least as new as it, never an older one."""
    from action_msgs.msg import GoalStatus
    from builtin_interfaces.msg import Time
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import PointCloud2

    from actaim2_ros.pointcloud2 import to_msg

    recorder, client, control = start_cell(start_node, ros_node, {
        "arm_action": "/no_such_controller/follow_joint_trajectory", "server_wait": 0.5, "use_cloud": True, "cloud_wait": 3.0})
    g = np.linspace(-0.1, 0.1, 21)
    plate = np.stack(np.meshgrid(0.55 + g, g), -1).reshape(-1, 2)  # 20 cm square, 40 cm high
    plate = np.column_stack([plate, np.full(len(plate), 0.40)]).astype(np.float32)
    latest = {"cloud": to_msg(plate, frame_id="world")}
    publisher = ros_node.create_publisher(PointCloud2, "/fused_points", qos_profile_sensor_data)
    # Runs until the fixture stops the executor: cancelling it while the executor spins can race the
    # executor's call of it ("timer is canceled", an exception never retrieved at exit).
    ros_node.create_timer(0.1, lambda: publisher.publish(latest["cloud"]))
    assert wait_for(lambda: "obstacle cloud" in control.output(), 20.0), control.output()

    under_the_plate = [0.55, 0.0, 0.25]  # the wrist would go through the plate
    status, result = client.execute(client.goal(0, under_the_plate, DOWN_QUAT, False))
    assert status == GoalStatus.STATUS_ABORTED and not result.success
    assert "environment_collision" in result.message and "point cloud" in result.message, result.message

    assert result.candidate == -1
    # The refused keypose with a fallback: nothing moves for the first, the alternative runs.
    position = [0.3, -0.35, 0.35]
    goal = client.goal(0, under_the_plate, DOWN_QUAT, False)
    goal.alternatives = [client.goal(0, position, DOWN_QUAT, False).keypose]
    status, result = client.execute(goal)
    assert status == GoalStatus.STATUS_SUCCEEDED and result.success and result.candidate == 1, result.message
    fallback_logs = [line for line in control.output().splitlines() if "executing alternatives[0]" in line]
    assert fallback_logs and "environment_collision" in fallback_logs[0], control.output()  # the log says why
    position_error, orientation_error = tcp_error(panda, recorder, position, DOWN_QUAT)
    assert position_error <= 0.005 and orientation_error <= np.radians(3.0)

    # A plate over the mirrored target, stamped 100 s; a keypose predicted from views of 200 s waits
    # for the cloud of 200 s, which (1 s later) shows the plate gone: planned around it, the target
    # is reached (planned around the plate it would collide, as above).
    mirrored = [0.3, 0.35, 0.35]
    over = (plate + np.array([mirrored[0] - 0.55, mirrored[1], 0.10], np.float32)).astype(np.float32)
    latest["cloud"] = to_msg(over, frame_id="world", stamp=Time(sec=100))
    time.sleep(0.5)
    newer = to_msg(np.array([[1.3, -0.5, 0.9]], np.float32), frame_id="world", stamp=Time(sec=200))
    later = threading.Timer(1.0, lambda: latest.update(cloud=newer))
    later.start()
    goal = client.goal(0, mirrored, DOWN_QUAT, False)
    goal.keypose.header.stamp = Time(sec=200)
    status, result = client.execute(goal)
    later.join()
    assert status == GoalStatus.STATUS_SUCCEEDED and result.success, result.message
    # No cloud as new as the keypose within cloud_wait: the goal fails saying so, nothing moves.
    goal.keypose.header.stamp = Time(sec=300)
    status, result = client.execute(goal)
    assert status == GoalStatus.STATUS_ABORTED and not result.success
    assert "no obstacle cloud on /fused_points stamped at or after the keypose (300.000 s) within 3 s" in result.message, result.message
    assert "the newest is stamped 200.000 s" in result.message, result.message
