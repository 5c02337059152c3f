"""The other process of tests/interfaces/test_cross_process.py: serves and echoes actaim2 interfaces.

* /sample_mode, /predict_keypose: answers computed from the request (so the test can check every
  field crossed the process boundary), or success=false and a message for a bad request;
* /execute_keypose: feedback steps, a result, cancellation, and an abort for a bad goal;
* /ortho_views -> /ortho_views/echo and /cloud -> /cloud/echo: every message re-published
  unchanged (clouds with sensor-data QoS), so data round-trips test -> peer -> test.

Run with the test's environment (same ROS_DOMAIN_ID); Ctrl-C (SIGINT) stops it with exit code 0.
"""
from __future__ import annotations

import time

from actaim2_msgs.action import ExecuteKeypose
from actaim2_msgs.msg import Keypose, OrthoViews
from actaim2_msgs.srv import PredictKeypose, SampleMode
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2

from actaim2_ros.main import spin

EXECUTION_STEPS = 10
STEP_SECONDS_AT_FULL_SPEED = 0.02  # 10 steps: 0.2 s at velocity_scaling 1


class InterfacePeer(Node):
    def __init__(self) -> None:
        super().__init__("interface_peer")
        group = ReentrantCallbackGroup()
        self.create_service(SampleMode, "/sample_mode", self._sample_mode, callback_group=group)
        self.create_service(PredictKeypose, "/predict_keypose", self._predict_keypose, callback_group=group)
        self._action_server = ActionServer(
            self, ExecuteKeypose, "/execute_keypose", self._execute,
            cancel_callback=lambda _goal: CancelResponse.ACCEPT, callback_group=group)
        views_qos = QoSProfile(depth=1)
        self._views_echo = self.create_publisher(OrthoViews, "/ortho_views/echo", views_qos)
        self.create_subscription(OrthoViews, "/ortho_views", self._views_echo.publish, views_qos)
        self._cloud_echo = self.create_publisher(PointCloud2, "/cloud/echo", qos_profile_sensor_data)
        self.create_subscription(PointCloud2, "/cloud", self._cloud_echo.publish, qos_profile_sensor_data)

    def _sample_mode(self, request: SampleMode.Request, response: SampleMode.Response) -> SampleMode.Response:
        if request.cluster < -1:
            response.success = False
            response.message = f"cluster must be -1 (sample from the prior) or >= 0, got {request.cluster}"
            return response
        response.success = True
        response.cluster = request.cluster if request.cluster >= 0 else int(request.seed % 3)
        response.embedding = [float(response.cluster), float(request.seed), 0.5]
        response.cluster_probabilities = [0.25, 0.25, 0.5]
        response.observation_stamp.sec = int(request.seed)
        return response

    def _predict_keypose(self, request: PredictKeypose.Request, response: PredictKeypose.Response) -> PredictKeypose.Response:
        if len(request.embedding) == 0:
            response.success, response.message = False, "embedding is empty: call /sample_mode first"
            return response
        if request.phase > Keypose.PHASE_MANIPULATE:
            response.success, response.message = False, f"unknown phase {request.phase} (expected 0..3)"
            return response
        response.success = True
        response.keypose.header.frame_id = "world"
        response.keypose.header.stamp = request.not_before
        response.keypose.pose.position.x = float(sum(request.embedding))
        response.keypose.pose.position.z = float(request.phase)
        response.keypose.pose.orientation.w = 1.0
        response.keypose.gripper_closed = request.gripper_closed
        response.keypose.phase = request.phase
        response.confidence = 0.75
        return response

    def _execute(self, goal_handle: ServerGoalHandle) -> ExecuteKeypose.Result:
        goal: ExecuteKeypose.Goal = goal_handle.request
        result = ExecuteKeypose.Result()
        if not 0.0 < goal.velocity_scaling <= 1.0:
            goal_handle.abort()
            result.message = f"velocity_scaling must be in (0, 1], got {goal.velocity_scaling}"
            return result
        for step in range(1, EXECUTION_STEPS + 1):
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
                result.message = "cancelled"
                return result
            time.sleep(STEP_SECONDS_AT_FULL_SPEED / goal.velocity_scaling)  # stands in for the motion
            goal_handle.publish_feedback(ExecuteKeypose.Feedback(phase=goal.keypose.phase, progress=step / EXECUTION_STEPS))
        goal_handle.succeed()
        result.success = True
        return result


if __name__ == "__main__":
    raise SystemExit(spin(InterfacePeer, "interface_peer", threads=4))
