"""Real PartNet-Mobility folders through sim_node's /reset_scene (object_path), over real DDS.

One node process (Azure Kinect rig, ray casting, physics as fast as possible) with its own
hull cache, preparing a small hand-made object at start-up (``prepare_objects``): each shared
object resets with its DoFs and limits, and the next /points2 cloud shows it; the arm, sent a
scripted push through the trajectory action, moves a real drawer (/object_state); bad folders
are answered with success=false and the reason, and the node keeps serving.
"""
from __future__ import annotations

import numpy as np
import pytest
from actaim2_msgs.srv import ResetScene
from control_msgs.action import FollowJointTrajectory, GripperCommand
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState, PointCloud2
from tf2_msgs.msg import TFMessage

from actaim2.sim.objects.partnet import read_object_folder
from actaim2.sim.objects.sizing import fit_object
from actaim2_ros.action_client import LockedActionClient
from actaim2_ros.pointcloud2 import from_msg
from actaim2_ros.transforms import TF_STATIC_LISTENER_QOS
from harness import NodeProcess, wait_for
from partnet_shared import OBJECTS, bad_folders, make_object, shared_partnet, urdf_limits
from test_sim_node import ARM, Inbox, send, stamp_ns, tf_static_chain, trajectory


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = shared_partnet()
    tmp = tmp_path_factory.mktemp("partnet_node")
    make_object(tmp / "prepared" / "cab")
    params = dict(rig="azure_kinect", render_path="raycast", sensor_noise="none", real_time_factor=0.0, camera_rate=2.0,
                  hull_cache=str(tmp / "hulls"), prepare_objects=str(tmp / "prepared"))
    node = NodeProcess("actaim2_sim", "sim_node", params, [], tmp)
    yield node, root, tmp
    node.stop()


def object_box(folder, hulls, seed: int, dof_fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """The object's world box after the same reset done without ROS."""
    from actaim2.sim.env import SimEnv
    from actaim2.sim.objects.loader import aabb

    env = SimEnv("panda", hull_cache=hulls)
    env.reset(folder=folder, seed=seed, dof_fraction=dof_fraction)
    return aabb(env.object.articulation)


def test_shared_objects_reset_by_path_report_their_dofs_and_show_in_the_cloud(setup, ros_node):
    node, root, tmp = setup
    client = ros_node.create_client(ResetScene, "/reset_scene")
    assert client.wait_for_service(timeout_sec=120.0), node.output()[-3000:]
    assert "prepared 1 object(s)" in node.output() and "meshes 1 decomposed, 3 convex" in node.output()
    tf = Inbox(ros_node, TFMessage, "/tf_static", TF_STATIC_LISTENER_QOS)
    clouds = Inbox(ros_node, PointCloud2, "/points2", qos_profile_sensor_data)
    T_world_optical = tf_static_chain(tf.wait(), "depth_camera_link")
    for name, (category, joints) in OBJECTS.items():
        future = client.call_async(ResetScene.Request(object_path=str(root / name), seed=2, dof_fraction=0.5))
        assert wait_for(future.done, 60.0)
        response = future.result()
        assert response.success, response.message
        assert response.object_id == name and list(response.dof_names) == list(joints)
        lower, upper = urdf_limits(joints, fit_object(read_object_folder(root / name)).scale)
        np.testing.assert_allclose(response.dof_lower, lower, atol=1e-3)
        np.testing.assert_allclose(response.dof_upper, upper, atol=1e-3)
        reset_ns = stamp_ns(response.stamp)
        assert wait_for(lambda: any(stamp_ns(m.header.stamp) >= reset_ns for m in clouds.messages), 30.0), name
        msg = next(m for m in clouds.messages if stamp_ns(m.header.stamp) >= reset_ns)
        xyz = from_msg(msg).xyz
        world = xyz[np.isfinite(xyz).all(axis=1)] @ T_world_optical[:3, :3].T + T_world_optical[:3, 3]
        lower, upper = object_box(root / name, tmp / "hulls", seed=2, dof_fraction=0.5)
        on_object = np.all((world > lower - 0.01) & (world < upper + 0.01), axis=1) & (world[:, 2] > 0.01)
        assert on_object.sum() > 200, f"{name}: {on_object.sum()} cloud points on the object"
    assert node.alive()


def test_bad_folders_are_answered_with_the_reason_and_the_node_keeps_serving(setup, ros_node, tmp_path):
    node, root, _ = setup
    client = ros_node.create_client(ResetScene, "/reset_scene")
    assert client.wait_for_service(timeout_sec=120.0)

    def call(path) -> ResetScene.Response:
        future = client.call_async(ResetScene.Request(object_path=str(path), dof_fraction=0.5))
        assert wait_for(future.done, 60.0)
        return future.result()

    for case, (folder, words) in bad_folders(tmp_path).items():
        response = call(folder)
        assert not response.success, case
        assert all(w in response.message for w in words), (case, response.message)
    response = call(root / "102456")
    assert response.success and response.object_id == "102456", response.message
    assert node.alive()


def test_the_arm_pushes_a_real_drawer_shut_through_the_trajectory_action(setup, ros_node):
    """The push is planned without ROS on the same reset (privileged: where the drawer's face
    is), then sent as joint targets; only /object_state says whether the drawer was there."""
    from actaim2.rollout.push import ScriptedPush
    from actaim2.sim.env import SimEnv

    node, root, tmp = setup
    folder, dof, scene = root / "40147", 1, dict(seed=2, dof_fraction=0.5)
    env = SimEnv("panda", hull_cache=tmp / "hulls")
    info = env.reset(folder=folder, **scene)
    pusher = ScriptedPush(env)
    plan = pusher.plan(dof)
    assert not isinstance(plan, str), plan
    times, positions = pusher.timing(plan)

    reset = ros_node.create_client(ResetScene, "/reset_scene")
    arm = LockedActionClient(ros_node, FollowJointTrajectory, "/joint_trajectory_controller/follow_joint_trajectory")
    gripper = LockedActionClient(ros_node, GripperCommand, "/gripper_controller/gripper_cmd")
    assert reset.wait_for_service(timeout_sec=120.0) and arm.wait_for_server(timeout_sec=60.0)
    assert gripper.wait_for_server(timeout_sec=60.0)
    future = reset.call_async(ResetScene.Request(object_path=str(folder), **scene))
    assert wait_for(future.done, 60.0) and future.result().success, future.result().message
    np.testing.assert_allclose(future.result().dof_initial, info.dof_initial, atol=1e-3)
    state = Inbox(ros_node, JointState, "/object_state")
    goal = GripperCommand.Goal()
    goal.command.position = 0.0  # fingers closed: the push is made with the fingertips
    accepted, _ = send(gripper, goal)
    assert accepted
    accepted, result = send(arm, trajectory(ARM, list(zip(times, positions))), timeout=60.0)
    assert accepted, "push trajectory refused"
    n = len(state.messages)
    state.wait(n + 1)
    moved = plan.sign * (state.messages[-1].position[dof] - info.dof_initial[dof]) / (info.dof_upper[dof] - info.dof_lower[dof])
    assert moved > 0.1, f"the drawer moved {moved:.1%} of its range ({result.error_string})"
