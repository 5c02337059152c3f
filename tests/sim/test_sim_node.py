"""sim_node over real DDS, from another process: clouds, frames, clock, /reset_scene, and the
ros2_control-like FollowJointTrajectory / GripperCommand servers (bad requests included).

Two node processes, one after the other (they serve the same names):
  * ``ring5_node``: the default ring5 rig through SAPIEN's renderer, robot hidden, so every
    cloud point must be floor or object - checked against the object's box computed here by
    loading the same scene without ROS;
  * ``kinect_node``: the azure_kinect rig through the ray-casting path, physics as fast as
    possible, shared by the controller and service tests (starting a node costs seconds).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from actaim2_msgs.srv import ResetScene
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory, GripperCommand
from rclpy.qos import qos_profile_sensor_data
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, PointCloud2, PointField
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from actaim2.robots import load_robot_spec
from actaim2_ros.action_client import LockedActionClient
from actaim2_ros.pointcloud2 import from_msg
from actaim2_ros.transforms import TF_STATIC_LISTENER_QOS, transform_to_matrix
from harness import NodeProcess, wait_for

SPEC = load_robot_spec("panda")
ARM = list(SPEC.arm_joints)
SCENE = dict(category="storage_furniture", instance=0, seed=0, dof_fraction=0.5)


@pytest.fixture
def ring5_node(start_node):
    """Function-scoped: it must be gone before the kinect node serves the same names."""
    return start_node("actaim2_sim", "sim_node", dict(rig="ring5", hide_robot=True, camera_rate=4.0, **SCENE))


@pytest.fixture(scope="module")
def kinect_node(tmp_path_factory):
    # ideal cameras: the floor check below is exact (the rig's default realism is tested in test_kinect_realism)
    params = dict(rig="azure_kinect", render_path="raycast", sensor_noise="none", real_time_factor=0.0, camera_rate=2.0, **SCENE)
    node = NodeProcess("actaim2_sim", "sim_node", params, [], tmp_path_factory.mktemp("kinect"))
    yield node
    node.stop()


class Inbox:
    """Messages of one topic, kept in arrival order."""

    def __init__(self, node, msg_type, topic: str, qos=10):
        self.messages: list = []
        self.sub = node.create_subscription(msg_type, topic, self.messages.append, qos)

    def wait(self, count: int = 1, timeout: float = 30.0) -> list:
        assert wait_for(lambda: len(self.messages) >= count, timeout), f"no message on {self.sub.topic_name}"
        return self.messages


def stamp_ns(stamp) -> int:
    return stamp.sec * 10**9 + stamp.nanosec


def tf_static_chain(messages: list[TFMessage], child: str) -> np.ndarray:
    """T_world_child composed from every /tf_static edge received."""
    edges = {t.child_frame_id: (t.header.frame_id, transform_to_matrix(t)) for m in messages for t in m.transforms}
    T = np.eye(4)
    while child != "world":
        assert child in edges, f"no /tf_static edge to {child}; have {sorted(edges)}"
        parent, T_pc = edges[child]
        T = T_pc @ T
        child = parent
    return T


def expected_object_box() -> tuple[np.ndarray, np.ndarray]:
    """The object's axis-aligned box in world, from the same reset done without ROS."""
    from actaim2.sim.env import SimEnv
    from actaim2.sim.objects.loader import aabb

    env = SimEnv("panda")
    env.reset(**SCENE)
    return aabb(env.object.articulation)


def test_ring5_clouds_land_on_the_floor_and_the_object(ring5_node, ros_node):
    tf = Inbox(ros_node, TFMessage, "/tf_static", TF_STATIC_LISTENER_QOS)
    clouds = {k: Inbox(ros_node, PointCloud2, f"/cameras/cam{k}/points", qos_profile_sensor_data) for k in range(5)}
    clock = Inbox(ros_node, Clock, "/clock")
    lower, upper = expected_object_box()
    for k, inbox in clouds.items():
        msg = inbox.wait(1, timeout=60.0)[-1]
        assert msg.header.frame_id == f"cam{k}_optical_frame"
        assert (msg.height, msg.width, msg.point_step, msg.row_step) == (240, 320, 32, 32 * 320)
        assert not msg.is_dense and not msg.is_bigendian
        assert [(f.name, f.offset, f.datatype, f.count) for f in msg.fields] == [
            ("x", 0, PointField.FLOAT32, 1), ("y", 4, PointField.FLOAT32, 1),
            ("z", 8, PointField.FLOAT32, 1), ("rgb", 16, PointField.FLOAT32, 1)]
        cloud = from_msg(msg)
        valid = np.isfinite(cloud.xyz).all(axis=1)
        assert valid.mean() > 0.5
        assert np.all(cloud.xyz[valid, 2] > 0)  # optical frame: in front of the camera
        T_world_optical = tf_static_chain(tf.wait(), msg.header.frame_id)
        world = cloud.xyz[valid] @ T_world_optical[:3, :3].T + T_world_optical[:3, 3]
        floor = np.abs(world[:, 2]) < 3e-3
        in_box = np.all((world > lower - 5e-3) & (world < upper + 5e-3), axis=1)
        assert floor.mean() > 0.2 and in_box.mean() > 0.05, f"cam{k}: floor {floor.mean():.2f}, object {in_box.mean():.2f}"
        # robot hidden: nothing but floor and object
        assert np.mean(floor | in_box) > 0.999, f"cam{k}: {np.sum(~(floor | in_box))} points elsewhere"
    np.testing.assert_allclose(tf_static_chain(tf.messages, SPEC.root_link), np.eye(4))
    ticks = clock.wait(3)
    seconds = [c.clock.sec + c.clock.nanosec * 1e-9 for c in ticks]
    assert seconds == sorted(seconds) and seconds[-1] > 0


def test_azure_kinect_points2_and_joint_states(kinect_node, ros_node):
    tf = Inbox(ros_node, TFMessage, "/tf_static", TF_STATIC_LISTENER_QOS)
    points = Inbox(ros_node, PointCloud2, "/points2", qos_profile_sensor_data)
    joints = Inbox(ros_node, JointState, "/joint_states")
    objects = Inbox(ros_node, JointState, "/object_state")
    msg = points.wait(1, timeout=60.0)[-1]
    assert (msg.header.frame_id, msg.height, msg.width) == ("depth_camera_link", 288, 320)
    edges = {(t.header.frame_id, t.child_frame_id) for m in tf.wait() for t in m.transforms}
    assert {("world", "camera_base"), ("camera_base", "depth_camera_link"), ("world", SPEC.root_link)} <= edges
    cloud = from_msg(msg)
    T_world_optical = tf_static_chain(tf.messages, "depth_camera_link")
    world = cloud.xyz[np.isfinite(cloud.xyz).all(axis=1)] @ T_world_optical[:3, :3].T + T_world_optical[:3, 3]
    assert np.mean(np.abs(world[:, 2]) < 1e-3) > 0.2  # ray casting is exact: the floor is at z = 0
    state = joints.wait()[-1]
    assert list(state.name) == ARM + list(SPEC.gripper_joints) and len(state.position) == 9
    assert len(objects.wait()[-1].name) >= 1


# -- controllers -------------------------------------------------------------------------------
def trajectory(names, points) -> FollowJointTrajectory.Goal:
    goal = FollowJointTrajectory.Goal()
    goal.trajectory = JointTrajectory(joint_names=list(names))
    for t, q in points:
        goal.trajectory.points.append(
            JointTrajectoryPoint(positions=list(q), time_from_start=Duration(sec=int(t), nanosec=int(round((t % 1) * 1e9)))))
    return goal


def send(client: LockedActionClient, goal, timeout: float = 30.0):
    """(accepted, result) of one goal, waiting for both."""
    future = client.send_goal_async(goal)
    assert wait_for(future.done, timeout), "no goal response"
    handle = future.result()
    if not handle.accepted:
        return False, None
    result = handle.get_result_async()
    assert wait_for(result.done, timeout), "no result"
    return True, result.result().result


def current_arm(joints: Inbox) -> np.ndarray:
    n = len(joints.messages)
    joints.wait(n + 1)
    state = joints.messages[-1]
    return np.array([state.position[list(state.name).index(j)] for j in ARM])


@pytest.fixture
def arm_client(kinect_node, ros_node):
    client = LockedActionClient(ros_node, FollowJointTrajectory, "/joint_trajectory_controller/follow_joint_trajectory")
    assert client.wait_for_server(timeout_sec=60.0), kinect_node.output()[-3000:]
    return client  # destroyed with ros_node (destroying it while the executor spins races)


def test_trajectory_goals_follow_jtc_semantics(arm_client, ros_node):
    joints = Inbox(ros_node, JointState, "/joint_states")
    q0 = current_arm(joints)
    target = q0 + np.array([0.3, 0.0, 0.0, 0.0, 0.0, 0.0, -0.2])
    accepted, result = send(arm_client, trajectory(ARM, [(0.5, (q0 + target) / 2), (1.0, target)]))
    assert accepted and result.error_code == FollowJointTrajectory.Result.SUCCESSFUL, result.error_string
    np.testing.assert_allclose(current_arm(joints), target, atol=0.02)

    # bad requests: refused with the FollowJointTrajectory error code and a reason; the arm stays
    bad = {
        "unknown joint": (trajectory(ARM[:-1] + ["elbow_joint"], [(1.0, target)]), FollowJointTrajectory.Result.INVALID_JOINTS,
                          "elbow_joint"),
        "NaN": (trajectory(ARM, [(1.0, [math.nan] + list(target[1:]))]), FollowJointTrajectory.Result.INVALID_GOAL, "non-finite"),
        "times": (trajectory(ARM, [(1.0, target), (0.5, q0)]), FollowJointTrajectory.Result.INVALID_GOAL, "strictly increasing"),
    }
    for what, (goal, code, reason) in bad.items():
        accepted, result = send(arm_client, goal)
        assert result is not None and result.error_code == code, what
        assert reason in result.error_string, (what, result.error_string)
    np.testing.assert_allclose(current_arm(joints), target, atol=0.02)

    # empty trajectory: hold position, done at once
    accepted, result = send(arm_client, trajectory(ARM, []))
    assert result.error_code == FollowJointTrajectory.Result.SUCCESSFUL

    # a new goal replaces the running one (preemption); the first ends with a reason
    slow = arm_client.send_goal_async(trajectory(ARM, [(60.0, q0)]))
    assert wait_for(slow.done, 10.0) and slow.result().accepted
    slow_result = slow.result().get_result_async()
    accepted, result = send(arm_client, trajectory(ARM, [(0.5, target)]))
    assert result.error_code == FollowJointTrajectory.Result.SUCCESSFUL
    assert wait_for(slow_result.done, 10.0)
    assert "preempted" in slow_result.result().result.error_string

    # cancel stops the arm where it is
    moving = arm_client.send_goal_async(trajectory(ARM, [(60.0, q0)]))
    assert wait_for(moving.done, 10.0)
    cancel = moving.result().cancel_goal_async()
    assert wait_for(cancel.done, 10.0)
    result = moving.result().get_result_async()
    assert wait_for(result.done, 10.0)
    assert result.result().status == 5  # action_msgs/GoalStatus.STATUS_CANCELED


def test_goals_sent_back_to_back_start_in_the_order_sent(arm_client, ros_node):
    """A teleop jogs by sending goals faster than they end: each must replace the one before it,
    so the arm ends at the last one sent, however the server's threads take them."""
    joints = Inbox(ros_node, JointState, "/joint_states")
    q0 = current_arm(joints)
    targets = [q0 + np.array([0.02 * (i + 1), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]) for i in range(8)]
    sent = [arm_client.send_goal_async(trajectory(ARM, [(0.5, q)])) for q in targets]
    assert wait_for(lambda: all(f.done() for f in sent), 30.0)
    assert all(f.result().accepted for f in sent)
    results = [f.result().get_result_async() for f in sent]
    assert wait_for(lambda: all(r.done() for r in results), 30.0)
    outcomes = [r.result().result for r in results]
    assert outcomes[-1].error_code == FollowJointTrajectory.Result.SUCCESSFUL, outcomes[-1].error_string
    # the others were replaced, or ended first (this node's physics runs as fast as it can)
    assert all(o.error_code == FollowJointTrajectory.Result.SUCCESSFUL or "preempted" in o.error_string
               for o in outcomes[:-1]), [o.error_string for o in outcomes]
    np.testing.assert_allclose(current_arm(joints), targets[-1], atol=0.01)


def test_jtc_topic_moves_the_arm(kinect_node, ros_node, arm_client):
    joints = Inbox(ros_node, JointState, "/joint_states")
    publisher = ros_node.create_publisher(JointTrajectory, "/joint_trajectory_controller/joint_trajectory", 10)
    assert wait_for(lambda: publisher.get_subscription_count() > 0, 30.0)
    target = np.array(SPEC.home) + 0.1
    publisher.publish(trajectory(ARM, [(0.5, target)]).trajectory)
    assert wait_for(lambda: np.allclose(current_arm(joints), target, atol=0.02), 30.0)


def test_gripper_reaches_or_stalls(kinect_node, ros_node):
    """Positions are gap widths (m between the fingers), as the message says."""
    client = LockedActionClient(ros_node, GripperCommand, "/gripper_controller/gripper_cmd")
    assert client.wait_for_server(timeout_sec=60.0)
    joints = Inbox(ros_node, JointState, "/joint_states")
    goal = GripperCommand.Goal()
    goal.command.position = 0.02
    accepted, result = send(client, goal)
    assert accepted and result.reached_goal and not result.stalled
    assert result.position == pytest.approx(0.02, abs=0.002)
    finger = SPEC.gripper_joints[0]  # each Panda finger moves half the gap
    assert wait_for(lambda: any(abs(dict(zip(m.name, m.position))[finger] - 0.01) < 0.001 for m in joints.messages[-5:]), 5.0)
    # beyond the closed limit: the fingers stop at 0 and never reach -0.01 -> stalled = success
    goal.command.position = -0.01
    accepted, result = send(client, goal)
    assert accepted and result.stalled and not result.reached_goal
    assert result.position == pytest.approx(SPEC.gripper_closed, abs=0.002)


def handle_grasp_path(scene: dict, back_off: float = 0.1, steps: int = 5) -> list[np.ndarray]:
    """Arm angles along the approach axis from ``back_off`` before the first handle's grasp pose
    to the grasp itself: privileged, from the same reset done without ROS."""
    from actaim2.control.ik import IKSolver
    from actaim2.control.model import RobotModel
    from actaim2.sim.env import SimEnv

    env = SimEnv("panda")
    env.reset(**scene)
    handle = env.object.handles[0]
    T_grasp = env.object.link(handle.link).entity_pose.to_transformation_matrix() @ handle.tcp_in_link()
    solver = IKSolver(RobotModel(SPEC), None)
    q, path = np.array(SPEC.home), []
    for distance in np.linspace(back_off, 0.0, steps):
        T = T_grasp.copy()
        T[:3, 3] -= distance * T_grasp[:3, 2]
        result = solver.solve(T, q, rng=np.random.default_rng(0))
        assert result.success, result.message
        q = result.angles
        path.append(q)
    return path


def test_gripper_closed_on_a_handle_stalls_with_default_parameters(kinect_node, ros_node):
    """PhysX reports a finger velocity (~1-3 mm/s) while the fingers squeeze the handle at a
    constant position: the default stall detection must still end the goal, stalled = success."""
    from action_msgs.msg import GoalStatus

    scene = dict(category="table", instance=0, seed=0, dof_fraction=0.5)
    reset = ros_node.create_client(ResetScene, "/reset_scene")
    assert reset.wait_for_service(timeout_sec=60.0)
    future = reset.call_async(ResetScene.Request(**scene))
    assert wait_for(future.done, 60.0) and future.result().success, future.result()
    path = handle_grasp_path(scene)

    arm = LockedActionClient(ros_node, FollowJointTrajectory, "/joint_trajectory_controller/follow_joint_trajectory")
    gripper = LockedActionClient(ros_node, GripperCommand, "/gripper_controller/gripper_cmd")
    assert arm.wait_for_server(timeout_sec=60.0) and gripper.wait_for_server(timeout_sec=60.0)
    accepted, result = send(arm, trajectory(ARM, [(1.5 + 0.25 * i, q) for i, q in enumerate(path)]))
    assert accepted and result.error_code == FollowJointTrajectory.Result.SUCCESSFUL, result.error_string

    goal = GripperCommand.Goal()
    goal.command.position = 0.0  # gap width: fully closed
    goal.command.max_effort = 25.0  # N: the squeeze on the handle
    sent = gripper.send_goal_async(goal)
    assert wait_for(sent.done, 30.0) and sent.result().accepted
    outcome = sent.result().get_result_async()
    assert wait_for(outcome.done, 30.0), "the gripper goal never ended on the handle"
    assert outcome.result().status == GoalStatus.STATUS_SUCCEEDED
    result = outcome.result().result
    assert result.stalled and not result.reached_goal
    assert 0.01 < result.position < 0.03, result.position  # the gap: the handle's bar is between the fingers
    assert result.effort == pytest.approx(25.0, rel=0.05)  # squeezing with max_effort, not the default 70 N


def test_reset_scene_answers_bad_requests_and_reports_dof_limits(kinect_node, ros_node):
    client = ros_node.create_client(ResetScene, "/reset_scene")
    assert client.wait_for_service(timeout_sec=60.0)

    def call(**fields) -> ResetScene.Response:
        future = client.call_async(ResetScene.Request(**fields))
        assert wait_for(future.done, 60.0)
        return future.result()

    response = call(category="spaceship", instance=0, dof_fraction=0.5)
    assert not response.success and "storage_furniture" in response.message and "faucet" in response.message
    response = call(category="storage_furniture", instance=999, dof_fraction=0.5)
    assert not response.success and "valid instances" in response.message
    response = call(category="storage_furniture", instance=0, dof_fraction=1.5)
    assert not response.success and "dof_fraction" in response.message
    response = call(object_path="/nonexistent/object", dof_fraction=0.5)
    assert not response.success and "/nonexistent/object" in response.message and "mobility.urdf" in response.message
    clouds = Inbox(ros_node, PointCloud2, "/points2", qos_profile_sensor_data)
    response = call(category="door", instance=1, seed=3, dof_fraction=0.25)
    assert response.success, response.message
    assert response.object_id == "door_001"
    # DESIGN.md: observations stamped at or after the reset's stamp show the new scene.
    reset_ns = stamp_ns(response.stamp)
    assert reset_ns > 0
    assert wait_for(lambda: any(stamp_ns(m.header.stamp) >= reset_ns for m in clouds.messages), 30.0)
    n = len(response.dof_names)
    assert n >= 1 and len(response.dof_lower) == len(response.dof_upper) == len(response.dof_initial) == n
    lower, upper, initial = map(np.array, (response.dof_lower, response.dof_upper, response.dof_initial))
    assert np.all(upper > lower)
    np.testing.assert_allclose(initial, lower + 0.25 * (upper - lower), atol=1e-3)
    objects = Inbox(ros_node, JointState, "/object_state")
    assert wait_for(lambda: objects.messages and list(objects.messages[-1].name) == list(response.dof_names), 30.0)
    # DESIGN.md: an empty category keeps the current one; instance -1 is drawn from the seed.
    drawn = [call(category="", instance=-1, seed=seed, dof_fraction=0.5) for seed in (7, 7, 8, 9, 10)]
    assert all(r.success and r.object_id.startswith("door_") for r in drawn), [r.message for r in drawn]
    assert drawn[0].object_id == drawn[1].object_id
    assert len({r.object_id for r in drawn}) > 1
    assert kinect_node.alive()
