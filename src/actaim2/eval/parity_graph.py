"""The ROS half of ``actaim2 parity``: a node graph in separate processes and one episode_runner per tuple.

The graph is ``actaim2 launch``'s (``actaim2_policy/launch/graphs.yaml``, default
``sim_panda_ring5``), every node started through ``ros2 run`` in its own process group, with
these overrides so that it executes what the library evaluation executes:

* sim_node: the library's render path;
* fusion_node and policy_node: the checkpoint's own perception configuration (a YAML written
  beside the results), and when its selector and predictor were trained with different robot
  filters, the alternate views topic for the predictor;
* policy_node: the checkpoint;
* control_node: ``use_cloud`` on, as the library plans around the object cloud (data
  collection's obstacles) while the node's default ignores the cloud.

Each tuple is one ``ros2 run actaim2_policy episode_runner`` process (episodes 1, the tuple's
object, seed and cluster, the library's velocity scaling and initial DoF fraction); its JSONL
record is the ROS outcome. Nothing here imports ROS: the graph is processes and files.
"""
from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import time
from pathlib import Path

from actaim2.launch.cli import command_lines, default_graphs_file, share_dir, stop_all
from actaim2.launch.graph import GRAPH_ENVIRONMENT, NodeSpec, load_graphs

ALTERNATE_VIEWS = "/ortho_views_predictor"
# Generous waits: on 2 shared cores the graph's start (SAPIEN's shaders, the policy's warm-up)
# takes a minute or more, and one answer can take seconds while the simulator renders.
RUNNER_TIMEOUTS = {"server_timeout": 600.0, "reset_timeout": 180.0, "call_timeout": 60.0, "views_timeout": 120.0,
                   "goal_timeout": 240.0}
EPISODE_WALL_LIMIT = 900.0  # s: an episode_runner still running after this is stopped and the tuple reported as an error


class ParityGraph:
    """The node graph: ``start`` it, ``episode`` runs one tuple, ``stop`` ends every node."""

    def __init__(self, graph: str, logs: Path, domain_id: int):
        graphs = load_graphs(default_graphs_file())
        if graph not in graphs:
            raise ValueError(f"unknown graph '{graph}'; graphs: {', '.join(graphs)}")
        self.graph = graphs[graph]
        self.logs = logs
        self.env = {**os.environ, **GRAPH_ENVIRONMENT, "ROS_DOMAIN_ID": str(domain_id)}
        self.procs: list[tuple[str, subprocess.Popen, Path]] = []

    def sim_parameter(self, name: str):
        """A parameter the graph gives sim_node (robot, rig): the library side must simulate the same."""
        return next(n.parameters.get(name) for n in self.graph.nodes if n.executable == "sim_node")

    def start(self, overrides: dict[str, dict]) -> None:
        """Every node, with ``overrides`` (node name -> parameters) over the graph's parameters."""
        unknown = set(overrides) - {n.name for n in self.graph.nodes}
        if unknown:
            raise ValueError(f"graph {self.graph.name} has no node(s) {sorted(unknown)}")
        self.graph = dataclasses.replace(self.graph, nodes=tuple(
            dataclasses.replace(n, parameters={**n.parameters, **overrides.get(n.name, {})}) for n in self.graph.nodes))
        self.logs.mkdir(parents=True, exist_ok=True)
        for spec, command in zip(self.graph.nodes, command_lines(self.graph)):
            self.procs.append((spec.name, *self._start(command, self.logs / f"{spec.name}.log")))

    def _start(self, command: list[str], log_path: Path) -> tuple[subprocess.Popen, Path]:
        with open(log_path, "w") as log:
            return subprocess.Popen(command, stdout=log, stderr=subprocess.STDOUT, env=self.env,
                                    start_new_session=True), log_path

    def dead(self) -> str | None:
        """The first node that exited, with its code and log, or None while all run."""
        for name, proc, log_path in self.procs:
            if proc.poll() is not None:
                return f"{name} exited with code {proc.returncode} (log {log_path})"
        return None

    def episode(self, index: int, category: str, instance: int, seed: int, cluster: int, velocity_scaling: float,
                dof_fraction: float, settle_time: float) -> dict:
        """One episode_runner process for one tuple: its record summarised, or {error}."""
        jsonl = self.logs / f"episode_{index:02d}.jsonl"
        params = {"keyposes": "policy", "episodes": 1, "categories": [category], "instances": [instance],
                  "clusters": [cluster], "seed": seed, "velocity_scaling": velocity_scaling, "dof_fraction": dof_fraction,
                  "settle_time": settle_time, "jsonl_file": str(jsonl.resolve()), **RUNNER_TIMEOUTS}
        spec = NodeSpec("actaim2_policy", "episode_runner", "episode_runner", (), params)
        command = ["ros2", "run", spec.package, spec.executable, *spec.ros_args(share_dir)]
        proc, log_path = self._start(command, self.logs / f"episode_{index:02d}.log")
        deadline = time.monotonic() + EPISODE_WALL_LIMIT
        while proc.poll() is None and time.monotonic() < deadline and self.dead() is None:
            time.sleep(0.5)
        if proc.poll() is None:
            stop_all([("episode_runner", proc, log_path)])
            return {"error": self.dead() or f"episode_runner still running after {EPISODE_WALL_LIMIT:.0f} s (log {log_path})"}
        lines = jsonl.read_text().splitlines() if jsonl.exists() else []
        if proc.returncode != 0 or len(lines) != 1:
            return {"error": f"episode_runner exited with code {proc.returncode}, {len(lines)} record(s) (log {log_path})"}
        record = json.loads(lines[0])
        return {"success": bool(record["success"]), "largest_change": float(record["largest_change"]),
                "phases_executed": sum(bool(p["executed"]) for p in record["phases"]), "cluster": record["cluster"],
                "object_id": record["object_id"], "note": record["note"], "seconds": round(record["seconds"], 1)}

    def stop(self) -> int:
        return stop_all(self.procs)
