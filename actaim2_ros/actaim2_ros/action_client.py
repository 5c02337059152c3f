"""rclpy's ActionClient without its request/response race (ros2/rclpy#1123).

rclpy 7.1 (the Jazzy wheels installed here) registers a goal, cancel or result request only
after sending it. Under a MultiThreadedExecutor another thread can take the server's answer in
between, find no request for it, log "Ignoring unexpected goal response. There may be more than
one action server for the action ..." and drop it: the request's future never completes, and
the caller sees a goal "not accepted" once its wait runs out (docs/control.md). Upstream fixed
it with a lock taken around sending-and-registering and around handling an answer
(ros2/rclpy#1308, backported to Jazzy in #1519); this class is that lock for the rclpy installed.
Feedback and status messages are handled outside the lock.
"""
from __future__ import annotations

import threading

from rclpy.action import ActionClient

RESPONSES = ("goal", "cancel", "result")


class LockedActionClient(ActionClient):
    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        # Reentrant: a future's done callback may send the next request from inside an answer.
        self._requests_lock = threading.RLock()

    def send_goal_async(self, *args, **kwargs):
        with self._requests_lock:
            return super().send_goal_async(*args, **kwargs)

    def _cancel_goal_async(self, goal_handle):
        with self._requests_lock:
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle):
        with self._requests_lock:
            return super()._get_result_async(goal_handle)

    async def execute(self, taken_data):
        answers = {key: value for key, value in taken_data.items() if key in RESPONSES}
        others = {key: value for key, value in taken_data.items() if key not in RESPONSES}
        if answers:
            with self._requests_lock:  # an answer waits until its request is registered
                await super().execute(answers)
        if others:
            await super().execute(others)
