"""pytest fixtures over the harness (tests/harness.py sets the ROS environment on import).

  ros_node    an rclpy Node in this process, spun by a background executor thread
  start_node  start `ros2 run <package> <executable>` with parameters; SIGINT at teardown
  make_trajectory  synthetic trajectories: a box on a floor seen by five cameras (below)
"""
from __future__ import annotations

import signal
from typing import TYPE_CHECKING, Callable, Iterator

import numpy as np
import pytest

from harness import NodeProcess

if TYPE_CHECKING:
    from rclpy.node import Node

    from actaim2.data.trajectory import CameraImage, Trajectory


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

# Synthetic trajectories for the data and viewer tests. The pictures are shaded like a render
# (flat colours, smooth depth) so PNG sizes are realistic enough for the size budget; the
# simulator-based tests measure the real thing.
def _picture(spec, shift: float) -> "CameraImage":
    """Floor (z = 0) and a 0.4 m box at (0.6 + shift, 0, 0.2) ray-cast analytically (floor only + box top/front)."""
    from actaim2.data.trajectory import CameraImage

    rays = spec.pixel_rays().reshape(-1, 3)
    T = spec.T_world_optical
    d = rays @ T[:3, :3].T
    o = T[:3, 3]
    t_floor = np.where(d[:, 2] < -1e-9, -o[2] / np.where(d[:, 2] < -1e-9, d[:, 2], -1), np.inf)
    lo, hi = np.array([0.4 + shift, -0.2, 0.0]), np.array([0.8 + shift, 0.2, 0.4])
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - o) / d, (hi - o) / d
    t_near = np.nanmax(np.minimum(t1, t2), axis=1)
    t_far = np.nanmin(np.maximum(t1, t2), axis=1)
    t_box = np.where((t_near <= t_far) & (t_far > 0), t_near, np.inf)
    t = np.minimum(t_floor, t_box)
    hit = np.isfinite(t) & (t < 5.0)
    depth = np.where(hit, t * rays[:, 2], 0.0).reshape(spec.height, spec.width)  # rays have z = 1 in optical frame
    rgb = np.zeros((spec.height * spec.width, 3), np.uint8)
    rgb[hit & (t_floor <= t_box)] = (90, 90, 100)
    rgb[hit & (t_box < t_floor)] = (160, 110, 60)
    return CameraImage(rgb.reshape(spec.height, spec.width, 3), depth.astype(np.float32), spec.K, spec.T_world_optical)


@pytest.fixture(scope="session")
def make_trajectory() -> Callable[..., "Trajectory"]:
    from actaim2.data.actions import ActionSequence
    from actaim2.data.trajectory import OBSERVATION_NAMES, ObjectState, Trajectory
    from actaim2.sim.cameras import ring5

    cameras = ring5(np.array([0.6, 0.0, 0.2]))
    pictures = {shift: {c.name: _picture(c, shift) for c in cameras} for shift in (0.0, 0.15)}

    def make(tid: str = "t-random-00000", category: str = "storage_furniture", instance: int = 0,
             split: str = "train_seen", sampler: str = "random", moved: float = 0.0) -> Trajectory:
        final = pictures[0.15 if abs(moved) > 0.3 else 0.0]
        observations = {name: pictures[0.0] for name in OBSERVATION_NAMES}
        observations["final"] = final
        action = ActionSequence(p1=np.array([0.4, 0.0, 0.3]), p2=np.array([0.3, 0.0, 0.3]), R0=np.eye(3), start_distance=0.12)
        return Trajectory(
            id=tid, object_id=f"{category}_{instance:03d}", category=category, instance=instance, split=split,
            sampler=sampler, seed=1, keyposes=action.keyposes(), observations=observations,
            robot_joints={name: {"panda_joint1": 0.1} for name in OBSERVATION_NAMES},
            object_state=ObjectState(["drawer"], np.array([0.0]), np.array([0.4]), np.array([0.2]), np.array([0.2 + 0.4 * moved])),
            info={"note": "synthetic"},
        )

    return make
