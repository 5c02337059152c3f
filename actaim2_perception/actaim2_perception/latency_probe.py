"""latency_probe: measures clouds-in to views-out of a running fusion_node (used by `actaim2 bench perception`).

It replays a scene file (``actaim2.bench.perception`` writes it: per camera an organized xyz
[+ rgb] cloud, its topic, frame and /tf_static chain; the robot's joint positions) at a fixed
rate, stamping every set with the current time, and matches each /ortho_views message to the
set it came from by header stamp. After ``duration`` seconds it prints one JSON line
(``latencies_ms`` of every answered set, ``sent``, ``received``, ``seconds``) and exits.
"""
from __future__ import annotations

import json
import time

import numpy as np
from actaim2_msgs.msg import OrthoViews
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import JointState, PointCloud2

from actaim2_ros.main import spin
from actaim2_ros.params import declare_parameters
from actaim2_ros.pointcloud2 import to_msg
from actaim2_ros.stamps import stamp_ns
from actaim2_ros.transforms import StaticTransformPublisher, matrix_to_transform

PARAMETERS = {
    "scene_file": ("", "npz written by actaim2.bench.perception.save_scene"),
    "rate": (10.0, "Hz at which cloud sets are published"),
    "duration": (8.0, "s of measurement after the node has answered once"),
    "warmup_timeout": (60.0, "s to wait for the first /ortho_views before giving up"),
}


class LatencyProbe(Node):
    def __init__(self) -> None:
        super().__init__("latency_probe")
        p = declare_parameters(self, PARAMETERS)
        scene = np.load(p["scene_file"], allow_pickle=False)
        n = int(scene["n_cameras"])
        self._clouds = [
            to_msg(scene[f"xyz{i}"], scene[f"rgb{i}"] if f"rgb{i}" in scene else None, str(scene[f"frame{i}"])) for i in range(n)
        ]
        self._publishers = [
            self.create_publisher(PointCloud2, str(scene[f"topic{i}"]), qos_profile_sensor_data) for i in range(n)
        ]
        edges = []
        for i in range(n):
            parents, children, matrices = scene[f"chain_parents{i}"], scene[f"chain_children{i}"], scene[f"chain_T{i}"]
            edges += [matrix_to_transform(T, str(a), str(b)) for a, b, T in zip(parents, children, matrices)]
        self._tf = StaticTransformPublisher(self)
        self._tf.send(edges)
        self._joints = JointState(name=[str(s) for s in scene["joint_names"]], position=[float(v) for v in scene["joint_positions"]])
        self._joint_pub = self.create_publisher(JointState, "/joint_states", 10)
        self.create_subscription(
            OrthoViews, "/ortho_views", self._on_views, QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
        )
        self._sent: dict[int, float] = {}
        self._latencies: list[float] = []
        self._measuring_since: float | None = None
        self._sent_while_measuring = 0
        self._duration = float(p["duration"])
        self._warmup_deadline = time.monotonic() + float(p["warmup_timeout"])
        self.done = False
        self.create_timer(1.0 / float(p["rate"]), self._tick)

    def _tick(self) -> None:
        now = time.monotonic()
        if self._measuring_since is None and now > self._warmup_deadline:
            self._finish("no /ortho_views received during warm-up")
            return
        if self._measuring_since is not None and now - self._measuring_since >= self._duration:
            self._finish(None)
            return
        stamp = self.get_clock().now()
        self._joints.header.stamp = stamp.to_msg()  # the self-filter poses the robot at the clouds' stamp
        self._joint_pub.publish(self._joints)
        for publisher, msg in zip(self._publishers, self._clouds):
            msg.header.stamp = stamp.to_msg()
            publisher.publish(msg)
        self._sent[stamp.nanoseconds] = time.monotonic()
        if self._measuring_since is not None:
            self._sent_while_measuring += 1

    def _on_views(self, msg: OrthoViews) -> None:
        arrived = time.monotonic()
        sent = self._sent.pop(stamp_ns(msg.header.stamp), None)
        if sent is None:
            return
        if self._measuring_since is None:  # the first answer ends the warm-up (discovery, first TF)
            self._measuring_since = arrived
            return
        self._latencies.append((arrived - sent) * 1e3)

    def _finish(self, error: str | None) -> None:
        if self.done:
            return
        seconds = time.monotonic() - self._measuring_since if self._measuring_since is not None else 0.0
        result = {"latencies_ms": self._latencies, "sent": self._sent_while_measuring, "received": len(self._latencies), "seconds": seconds}
        if error:
            result["error"] = error
        print(json.dumps(result), flush=True)
        self.done = True
        self.context.try_shutdown()  # ends actaim2_ros.main.spin


def main(args: list[str] | None = None) -> int:
    return spin(LatencyProbe, "latency_probe", args)


if __name__ == "__main__":
    raise SystemExit(main())
