"""One node list, two launchers: the committed ROS XML launch files say exactly what
`actaim2 launch` starts, and `actaim2 launch` starts, reports and stops real node processes."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from tf2_msgs.msg import TFMessage

from actaim2.launch import cli as launch_cli
from actaim2.launch.cli import command_lines, default_graphs_file, share_dir, stop_all
from actaim2.launch.graph import (
    GraphError,
    NodeSpec,
    expand_share,
    load_graphs,
    parse_launch_xml,
    to_launch_xml,
)
from actaim2_ros.transforms import TF_STATIC_LISTENER_QOS
from harness import REPO, wait_for

GRAPHS = load_graphs(REPO / "actaim2_policy" / "launch" / "graphs.yaml")


def test_the_three_graphs_of_design_exist_and_the_installed_list_is_the_source_one():
    assert {"sim_panda_ring5", "sim_kinova_azure", "real_kinova_azure"} <= set(GRAPHS)
    assert "sim_node" not in {n.executable for n in GRAPHS["real_kinova_azure"].nodes}
    assert default_graphs_file().read_text() == (REPO / "actaim2_policy" / "launch" / "graphs.yaml").read_text()


@pytest.mark.parametrize("name", sorted(GRAPHS))
def test_committed_launch_xml_is_generated_from_the_node_list(name):
    committed = (REPO / "actaim2_policy" / "launch" / f"{name}.launch.xml").read_text()
    assert committed == to_launch_xml(GRAPHS[name]), "regenerate: actaim2 launch --write-xml actaim2_policy/launch"


def parse_ros2_run(cmd: list[str]) -> NodeSpec:
    """A `ros2 run` command line back into what it starts (the inverse of NodeSpec.ros_args)."""
    assert cmd[:2] == ["ros2", "run"] and cmd[4] == "--ros-args", cmd
    name, files, parameters, remaps = None, [], {}, {}
    args = iter(cmd[5:])
    for flag in args:
        value = next(args)
        if flag == "--params-file":
            files.append(value)
        elif flag == "-p":
            key, _, v = value.partition(":=")
            parameters[key] = v
        elif flag == "-r" and value.startswith("__node:="):
            name = value.removeprefix("__node:=")
        elif flag == "-r":
            source, _, target = value.partition(":=")
            remaps[source] = target
        else:
            raise AssertionError(f"unexpected argument {flag} in {cmd}")
    return NodeSpec(cmd[2], cmd[3], name, tuple(files), parameters, remaps)


@pytest.mark.parametrize("name", sorted(GRAPHS))
def test_launch_xml_nodes_parameters_and_remappings_equal_what_actaim2_launch_starts(name):
    from_xml = parse_launch_xml((REPO / "actaim2_policy" / "launch" / f"{name}.launch.xml").read_text())
    every_argument = dict.fromkeys(GRAPHS[name].arguments, True)  # the XML lists optional nodes
    started = [parse_ros2_run(cmd) for cmd in command_lines(GRAPHS[name], every_argument)]
    assert len(from_xml) == len(started) > 0
    for xml_node, run_node in zip(from_xml, started):
        assert (xml_node.package, xml_node.executable, xml_node.name) == (run_node.package, run_node.executable, run_node.name)
        resolved = tuple(str(Path(share_dir(f.split("/")[0])) / f.split("/", 1)[1]) for f in xml_node.params_files)
        assert resolved == run_node.params_files
        assert all(Path(f).is_file() for f in resolved), resolved
        assert {k: expand_share(v, share_dir) for k, v in xml_node.parameters.items()} == run_node.parameters
        assert xml_node.remappings == run_node.remappings


@pytest.mark.parametrize("name", sorted(GRAPHS))
def test_viz_node_starts_only_with_viz_true_and_unknown_arguments_are_refused(name, capsys):
    graph = GRAPHS[name]
    xml = (REPO / "actaim2_policy" / "launch" / f"{name}.launch.xml").read_text()
    xml_conditions = {n.executable: n.condition for n in parse_launch_xml(xml)}
    assert xml_conditions["viz_node"] == "viz" and graph.arguments == {"viz": False}
    assert "viz_node" not in {n.executable for n in graph.started({})}
    assert "viz_node" in {n.executable for n in graph.started({"viz": True})}
    assert launch_cli.main(launch_cli_args([name, "viz:=true", "--dry-run"])) == 0
    assert "actaim2_policy viz_node" in capsys.readouterr().out
    assert launch_cli.main(launch_cli_args([name, "rviz:=true", "--dry-run"])) == 2
    assert "no argument(s) ['rviz']" in capsys.readouterr().err
    assert launch_cli.main(launch_cli_args([name, "viz:=maybe", "--dry-run"])) == 2
    assert "is not name:=true or name:=false" in capsys.readouterr().err


def launch_cli_args(argv: list[str]):
    import argparse

    parser = argparse.ArgumentParser()
    launch_cli.add_arguments(parser)
    return parser.parse_args(argv)


def test_bad_graph_files_are_refused_with_the_reason(tmp_path):
    bad = tmp_path / "graphs.yaml"
    bad.write_text("g:\n  nodes:\n    - {package: a}\n")
    with pytest.raises(GraphError, match="needs package and executable"):
        load_graphs(bad)
    bad.write_text("g:\n  nodes:\n    - {package: a, executable: b}\n    - {package: c, executable: b}\n")
    with pytest.raises(GraphError, match="duplicate node names"):
        load_graphs(bad)
    with pytest.raises(GraphError, match="cannot read"):
        load_graphs(tmp_path / "missing.yaml")
    bad.write_text("g:\n  nodes:\n    - {package: a, executable: b, if: viz}\n")
    with pytest.raises(GraphError, match="undeclared argument"):
        load_graphs(bad)


def launch(graphs: Path, graph: str, logs: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "actaim2.cli", "launch", graph, "--graphs", str(graphs), "--logs", str(logs)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)


def test_actaim2_launch_starts_every_node_and_ctrl_c_stops_them_all(tmp_path, ros_node):
    graphs = tmp_path / "graphs.yaml"
    calibration = "$(find-pkg-share actaim2_perception)/config/azure_kinect_calibration.yaml"
    # Both publishers remapped: a latched world -> camera_base on /tf_static would reach later tests.
    graphs.write_text(
        "pair:\n  nodes:\n"
        f"    - {{package: actaim2_perception, executable: calibration_publisher, name: calib_a, parameters: {{calibration_file: '{calibration}'}},"
        " remappings: {/tf_static: /tf_static_a}}\n"
        f"    - {{package: actaim2_perception, executable: calibration_publisher, name: calib_b, parameters: {{calibration_file: '{calibration}'}},"
        " remappings: {/tf_static: /tf_static_b}}\n")
    got = {"/tf_static_a": [], "/tf_static_b": []}
    for topic, inbox in got.items():
        ros_node.create_subscription(TFMessage, topic, inbox.append, TF_STATIC_LISTENER_QOS)
    proc = launch(graphs, "pair", tmp_path / "logs")
    try:
        assert wait_for(lambda: all(got.values()), 60.0), (proc.poll(), {k: len(v) for k, v in got.items()})
        assert wait_for(lambda: {"calib_a", "calib_b"} <= set(ros_node.get_node_names()), 30.0), ros_node.get_node_names()
    finally:
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C, as a user would (also after a failed assertion: no node left behind)
        out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out
    assert "calib_a stopped" in out and "calib_b stopped" in out
    assert (tmp_path / "logs" / "pair" / "calib_a.log").read_text()


def test_a_node_that_dies_is_reported_with_its_log_and_the_graph_stops(tmp_path):
    graphs = tmp_path / "graphs.yaml"
    graphs.write_text(
        "g:\n  nodes:\n"
        "    - {package: actaim2_perception, executable: calibration_publisher, name: ok, parameters: "
        "{calibration_file: '$(find-pkg-share actaim2_perception)/config/azure_kinect_calibration.yaml'}}\n"
        "    - {package: actaim2_perception, executable: calibration_publisher, name: broken, parameters: {calibration_file: /no/such.yaml}}\n")
    proc = launch(graphs, "g", tmp_path / "logs")
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 1, out
    log = tmp_path / "logs" / "g" / "broken.log"
    assert "broken exited with code" in out and str(log) in out, out
    assert "/no/such.yaml" in log.read_text()
    assert "ok stopped" in out


# A node (started as every node executable is, through actaim2_ros.main.spin) that hangs in its shutdown.
HANGING_NODE = textwrap.dedent("""
    import sys, time
    from rclpy.node import Node
    from actaim2_ros.main import spin

    def hang_in_destroy_node():
        while True:
            time.sleep(0.1)

    class Hangs(Node):
        def __init__(self):
            super().__init__("hangs_on_shutdown")
            print("node up", flush=True)

        def destroy_node(self):
            hang_in_destroy_node()

    sys.exit(spin(Hangs, "hangs_on_shutdown"))
""")


def test_a_node_that_does_not_stop_leaves_its_stacks_in_its_log_and_is_killed(tmp_path, monkeypatch, capsys):
    log_path = tmp_path / "hangs.log"
    with open(log_path, "w") as log:
        proc = subprocess.Popen([sys.executable, "-c", HANGING_NODE], stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        assert wait_for(lambda: "node up" in log_path.read_text(), 60.0), log_path.read_text()
        monkeypatch.setattr(launch_cli, "STOP_TIMEOUT", 3.0)
        assert stop_all([("hangs", proc, log_path)]) == 1
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == -signal.SIGKILL
    assert "did not stop within 3 s" in capsys.readouterr().err
    stacks = log_path.read_text()
    assert "most recent call first" in stacks and "in hang_in_destroy_node" in stacks, stacks
