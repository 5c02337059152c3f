"""pytest fixtures over the harness (tests/harness.py sets the ROS environment on import).

  ros_node    an rclpy Node in this process, spun by a background executor thread
  start_node  start `ros2 run <package> <executable>` with parameters; SIGINT at teardown
"""
from __future__ import annotations

import signal
from typing import TYPE_CHECKING, Callable, Iterator

import pytest

from harness import NodeProcess

if TYPE_CHECKING:
    from rclpy.node import Node


@pytest.fixture(scope="session")
def ros_context() -> Iterator[None]:
    import rclpy

    rclpy.init()
    yield
    rclpy.try_shutdown()


@pytest.fixture
def ros_node(ros_context, request) -> Iterator["Node"]:
    from rclpy.node import Node

    from actaim2_ros.main import BackgroundSpinner

    node = Node(f"test_{request.node.name}".replace("[", "_").replace("]", "_").replace("-", "_")[:60])
    spinner = BackgroundSpinner(node)
    yield node
    spinner.stop()  # no callback left running when the node is destroyed
    spinner.executor.shutdown()
    node.destroy_node()


@pytest.fixture
def start_node(tmp_path) -> Iterator[Callable[..., NodeProcess]]:
    started: list[NodeProcess] = []

    def _start(package: str, executable: str, params: dict | None = None, args: list[str] | None = None) -> NodeProcess:
        node = NodeProcess(package, executable, params, list(args or []), tmp_path)
        started.append(node)
        return node

    yield _start
    for node in reversed(started):
        if node.stop() not in (0, -signal.SIGINT, 130):
            print(f"--- {node.name} exited with {node.proc.returncode}; its output:\n{node.log_path.read_text(errors='replace')[-4000:]}")
