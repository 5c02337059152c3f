"""The committed sim bags (a scripted-teleop pull and push recorded with the azure_kinect rig,
bags/README.md) played by bag_player into fusion_node: every frame it publishes matches the golden
outputs within the tolerances stated in tests/bags/golden.py."""
from __future__ import annotations

import threading

import numpy as np
import pytest
from actaim2_msgs.msg import OrthoViews
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2

import golden
from actaim2_ros.pointcloud2 import from_msg
from harness import REPO, wait_for

BAGS = [REPO / "bags" / "sim_azure_kinect_pull", REPO / "bags" / "sim_azure_kinect_push"]


class Outputs:
    """fusion_node's /fused_points and /ortho_views by header stamp."""

    def __init__(self, node) -> None:
        self._lock = threading.Lock()
        self.fused: dict[int, np.ndarray] = {}
        self.views: dict[int, np.ndarray] = {}
        node.create_subscription(PointCloud2, "/fused_points", self._on_fused, qos_profile_sensor_data)
        node.create_subscription(OrthoViews, "/ortho_views", self._on_views, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))

    @staticmethod
    def _stamp(msg) -> int:
        return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec

    def _on_fused(self, msg: PointCloud2) -> None:
        xyz = from_msg(msg).xyz
        with self._lock:
            self.fused[self._stamp(msg)] = xyz

    def _on_views(self, msg: OrthoViews) -> None:
        views = np.asarray(msg.data, dtype=np.float32).reshape(len(msg.views), len(msg.channels), msg.height, msg.width)
        with self._lock:
            self.views[self._stamp(msg)] = views

    def frames(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        with self._lock:
            return {s: (self.fused[s], self.views[s]) for s in self.views if s in self.fused}


@pytest.mark.parametrize("bag", BAGS, ids=[b.name for b in BAGS])
def test_replay_into_fusion_node_matches_the_golden_outputs(bag, ros_node, start_node):
    expected = golden.load(bag)
    outputs = Outputs(ros_node)
    # joint_state_wait 1 s: on a loaded machine the JointState after a cloud may come late; the
    # node would then extrapolate the robot's pose instead of interpolating it as the reference does
    fusion = start_node("actaim2_perception", "fusion_node", {"robot": golden.ROBOT, "perception_config": golden.PERCEPTION,
                                                              "joint_state_wait": 1.0})
    # The player waits for fusion_node's subscriptions only: the first frame's outputs are lost
    # unless this test's subscriptions have discovered fusion_node's publishers before it plays.
    assert wait_for(lambda: ros_node.count_publishers("/fused_points") >= 1 and ros_node.count_publishers("/ortho_views") >= 1,
                    60.0), fusion.output()
    player = start_node("actaim2_policy", "bag_player", {"bag": str(bag), "topics": ["/points2", "/joint_states", "/tf_static"],
                                                          "wait_for_subscribers": ["/points2", "/joint_states"]})
    assert wait_for(lambda: not player.alive(), 120.0), player.output()
    assert player.proc.returncode == 0, player.output()
    stamps = {int(s) for s in expected["stamp"]}
    wait_for(lambda: stamps <= set(outputs.frames()), 10.0)
    problems = golden.compare(expected, outputs.frames())
    assert not problems, "\n".join(problems) + "\n" + fusion.output()[-3000:]
    assert len(expected["stamp"]) >= 10  # the bag is an episode, not a few frames
