"""`actaim2 launch GRAPH`: start a node graph as separate processes (no `launch` package here).

    actaim2 launch sim_panda_ring5                 # every node of the graph, logs in runs/launch/<graph>/
    actaim2 launch sim_panda_ring5 viz:=true       # with viz_node (the live Foxglove view)
    actaim2 launch sim_panda_ring5 --dry-run       # print the command lines only
    actaim2 launch --write-xml actaim2_policy/launch   # regenerate the ROS XML launch files

The nodes and their parameters come from the same list (``actaim2_policy/launch/graphs.yaml``)
as the XML launch files a real ROS 2 install uses with ``ros2 launch``. Each node runs through
``ros2 run`` in its own process group; Ctrl-C (or SIGTERM) sends SIGINT to every node and waits
for them, a node that dies is reported with its exit code and log path, and the others are
stopped (as ``ros2 launch`` does with required nodes).
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from actaim2.launch.graph import (
    GRAPH_ENVIRONMENT,
    Graph,
    GraphError,
    NodeSpec,
    load_graphs,
    parse_arguments,
    to_launch_xml,
)
from actaim2.runtime import STACK_DUMP_SIGNAL

STOP_TIMEOUT = 10.0  # s a node gets to exit after SIGINT before it is killed
STACK_DUMP_WAIT = 0.5  # s between asking a node that did not stop for its stacks and killing it
POLL = 0.2


def default_graphs_file() -> Path:
    """The installed graphs.yaml (share/actaim2_policy/launch), else the source tree's."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

        installed = Path(get_package_share_directory("actaim2_policy")) / "launch" / "graphs.yaml"
        if installed.is_file():
            return installed
    except (ImportError, PackageNotFoundError):
        pass
    return Path(__file__).resolve().parents[3] / "actaim2_policy" / "launch" / "graphs.yaml"


def share_dir(package: str) -> str:
    from ament_index_python.packages import get_package_share_directory

    return get_package_share_directory(package)


def command_lines(graph: Graph, arguments: dict[str, bool] | None = None) -> list[list[str]]:
    """The ``ros2 run`` command of every node that starts with the launch ``arguments`` (the
    graph's defaults for those not given), in graph order."""
    return [["ros2", "run", spec.package, spec.executable, *spec.ros_args(share_dir)]
            for spec in graph.started(arguments or {})]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("graph", nargs="?", help="graph name (see --list)")
    parser.add_argument("arguments", nargs="*", metavar="NAME:=VALUE",
                        help="launch arguments of the graph, e.g. viz:=true (see --list)")
    parser.add_argument("--graphs", type=Path, default=None, help="graphs YAML (default: actaim2_policy's launch/graphs.yaml)")
    parser.add_argument("--logs", type=Path, default=Path("runs/launch"), help="one log file per node under LOGS/<graph>/")
    parser.add_argument("--dry-run", action="store_true", help="print the command lines and exit")
    parser.add_argument("--list", action="store_true", help="list the graphs and exit")
    parser.add_argument("--write-xml", type=Path, metavar="DIR", help="write <graph>.launch.xml for every graph into DIR")


def main(args: argparse.Namespace) -> int:
    try:
        graphs = load_graphs(args.graphs or default_graphs_file())
    except GraphError as error:
        print(f"actaim2 launch: {error}", file=sys.stderr)
        return 2
    if args.write_xml:
        args.write_xml.mkdir(parents=True, exist_ok=True)
        for graph in graphs.values():
            (args.write_xml / f"{graph.name}.launch.xml").write_text(to_launch_xml(graph))
            print(f"wrote {args.write_xml / f'{graph.name}.launch.xml'}")
        return 0
    if args.list or not args.graph:
        for graph in graphs.values():
            arguments = "".join(f" {k}:={str(v).lower()}" for k, v in graph.arguments.items())
            nodes = ", ".join(n.name for n in graph.nodes)
            print(f"{graph.name:20s} {graph.description}  [{nodes}]{arguments}")
        return 0 if args.list else 2
    if args.graph not in graphs:
        print(f"actaim2 launch: unknown graph '{args.graph}'; graphs: {', '.join(graphs)}", file=sys.stderr)
        return 2
    graph = graphs[args.graph]
    try:
        arguments = parse_arguments(args.arguments)
        commands = command_lines(graph, arguments)
    except GraphError as error:
        print(f"actaim2 launch: {error}", file=sys.stderr)
        return 2
    if args.dry_run:
        for cmd in commands:
            print(" ".join(cmd))
        return 0
    return run_graph(graph.started(arguments), commands, args.logs / graph.name)


def run_graph(nodes: tuple[NodeSpec, ...], commands: list[list[str]], log_dir: Path) -> int:
    """Start every node, wait until Ctrl-C/SIGTERM or until one exits, then stop them all."""
    log_dir.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, **GRAPH_ENVIRONMENT}
    stop = {"signal": None}

    def request_stop(signum, _frame) -> None:
        stop["signal"] = signum

    previous = {s: signal.signal(s, request_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    procs: list[tuple[str, subprocess.Popen, Path]] = []
    try:
        for spec, cmd in zip(nodes, commands):
            log_path = log_dir / f"{spec.name}.log"
            with open(log_path, "w") as log:
                procs.append((spec.name, subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env,
                                                          start_new_session=True), log_path))
            print(f"[launch] started {spec.name} (pid {procs[-1][1].pid}, log {log_path})", flush=True)
        failed = None
        while stop["signal"] is None and failed is None:
            time.sleep(POLL)
            failed = next(((name, p, log) for name, p, log in procs if p.poll() is not None), None)
        if failed is not None:
            name, proc, log_path = failed
            print(f"[launch] {name} exited with code {proc.returncode}; its log: {log_path}. Stopping the graph.",
                  file=sys.stderr, flush=True)
        return stop_all(procs) if failed is None else max(1, stop_all(procs))
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def stop_all(procs: list[tuple[str, subprocess.Popen, Path]]) -> int:
    """SIGINT to every running node (its process group: ros2 run execs the node), then, after
    STOP_TIMEOUT, the stack dump signal and SIGKILL; returns 0 when every node exited cleanly (0, or -SIGINT)."""
    for _, proc, _ in procs:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
    deadline = time.monotonic() + STOP_TIMEOUT
    worst = 0
    for name, proc, log_path in procs:
        try:
            code = proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, STACK_DUMP_SIGNAL)  # a node started by actaim2_ros.main writes where its threads are
            time.sleep(STACK_DUMP_WAIT)
            os.killpg(proc.pid, signal.SIGKILL)
            code = proc.wait()
            print(f"[launch] {name} did not stop within {STOP_TIMEOUT:.0f} s: killed; its threads' stacks are at the end "
                  f"of its log ({log_path})", file=sys.stderr)
        if code not in (0, -signal.SIGINT):
            worst = 1
        print(f"[launch] {name} stopped (exit code {code})", flush=True)
    return worst
