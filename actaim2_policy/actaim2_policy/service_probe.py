"""service_probe: the client half of `actaim2 bench services` (benchmark only).

Publishes one set of views from a file (as fusion_node would), waits until policy_node answers
from them, then times ``calls`` round trips of one service (/predict_keypose: the phases in
turn), each from request sent to response received in this process, and writes them to
``summary_file`` as JSON. It exits by itself. One service per run lets the benchmark read the
node's CPU time per call: with ``node_pid`` the probe reads it from /proc around the timed calls.
"""
from __future__ import annotations

import json
import threading
import time

import numpy as np
from actaim2_msgs.msg import OrthoViews
from actaim2_msgs.srv import PredictKeypose, SampleMode
from rclpy.node import Node

from actaim2.keypose import PHASE_NAMES
from actaim2.profiling import cpu_seconds
from actaim2_policy.policy_node import VIEWS_QOS
from actaim2_ros.main import run_client
from actaim2_ros.params import declare_parameters

PARAMETERS = {
    "views_file": ("", "npz: data (V, C, H, W) float32, views, channels, digest (actaim2.bench.services.save_views)"),
    "service": ("predict_keypose", "the service timed: sample_mode | predict_keypose"),
    "calls": (200, "timed round trips"),
    "ready_timeout": (120.0, "s to wait for policy_node to answer from the published views"),
    "summary_file": ("", "JSON written at the end: milliseconds per call, the node's CPU milliseconds per call"),
    "node_pid": (0, "pid of policy_node (same machine) whose CPU time is read around the timed calls; 0 = not read"),
}


class ServiceProbe(Node):
    def __init__(self) -> None:
        super().__init__("service_probe")
        self.p = declare_parameters(self, PARAMETERS)
        if self.p["service"] not in ("sample_mode", "predict_keypose"):
            raise ValueError(f"service '{self.p['service']}' is not sample_mode or predict_keypose")
        views = np.load(self.p["views_file"], allow_pickle=False)
        self.views = OrthoViews(height=int(views["data"].shape[2]), width=int(views["data"].shape[3]),
                                views=[str(v) for v in views["views"]], channels=[str(c) for c in views["channels"]],
                                data=views["data"].astype(np.float32).ravel().tolist(), config_digest=str(views["digest"]))
        self.views.header.frame_id = "world"
        self.views_pub = self.create_publisher(OrthoViews, "/ortho_views", VIEWS_QOS)
        self.sample = self.create_client(SampleMode, "/sample_mode")
        self.predict = self.create_client(PredictKeypose, "/predict_keypose")

    def call(self, client, request):
        """(response, round trip in ms)."""
        done = threading.Event()
        started = time.perf_counter()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        if not done.wait(30.0):
            raise RuntimeError(f"no answer from {client.srv_name} within 30 s")
        return future.result(), 1000.0 * (time.perf_counter() - started)

    def run(self) -> dict:
        deadline = time.monotonic() + float(self.p["ready_timeout"])
        if not self.sample.wait_for_service(timeout_sec=float(self.p["ready_timeout"])):
            raise RuntimeError("/sample_mode did not appear")
        while True:  # views, then an answer made from them
            self.views.header.stamp = self.get_clock().now().to_msg()
            self.views_pub.publish(self.views)
            first, _ = self.call(self.sample, SampleMode.Request(cluster=-1, seed=0))
            if first.success:
                break
            if time.monotonic() > deadline:
                raise RuntimeError(f"policy_node did not answer from the views: {first.message}")
            time.sleep(0.2)
        timed, cpu = [], self.node_cpu()
        for k in range(int(self.p["calls"])):
            if self.p["service"] == "sample_mode":
                answer, ms = self.call(self.sample, SampleMode.Request(cluster=-1, seed=k))
            else:
                request = PredictKeypose.Request(embedding=first.embedding, phase=k % len(PHASE_NAMES), gripper_closed=k % 4 == 3)
                answer, ms = self.call(self.predict, request)
            assert answer.success, answer.message
            timed.append(ms)
        cpu_ms = 1000.0 * (self.node_cpu() - cpu) / len(timed) if self.p["node_pid"] else float("nan")
        return {"service": self.p["service"], "ms": timed, "node_cpu_ms": cpu_ms, "embedding": len(first.embedding),
                "served": first.message}

    def node_cpu(self) -> float:
        """policy_node's CPU seconds so far (utime + stime), 0 when no pid was given."""
        if not self.p["node_pid"]:
            return 0.0
        return cpu_seconds(self.p["node_pid"])


def probe(node: ServiceProbe, _stop: threading.Event) -> int:
    """Time the calls and write the summary: 0, or 1 with the reason logged."""
    try:
        summary = node.run()
    except (RuntimeError, AssertionError) as exc:
        node.get_logger().error(str(exc))
        return 1
    with open(node.p["summary_file"], "w") as f:
        json.dump(summary, f)
    return 0


def main(args: list[str] | None = None) -> int:
    # rclpy's own Ctrl-C handling: a benchmark client has no goal to cancel.
    return run_client(lambda _stop: ServiceProbe(), probe, "service_probe", args, own_signals=False)


if __name__ == "__main__":
    raise SystemExit(main())
