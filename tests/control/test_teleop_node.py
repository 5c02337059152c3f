"""teleop_node in a pseudo-terminal against the real sim_node and control_node: the key map, jogs that
move the arm, a refusal with IK's reason, the four keyposes executed and published on /keypose,
the mode label and the episode on /interaction_mode and /episode, and quitting."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import yaml

from actaim2.control.model import RobotModel
from actaim2.robots import load_robot_spec
from harness import matched, wait_for

SIM_PARAMS = {"robot": "panda", "camera_rate": 0.0, "render_path": "raycast", "category": "table", "instance": 0, "seed": 0}
TELEOP_PARAMS = {"robot": "panda", "translation_step": 0.02, "max_speed": 0.2, "object_id": "table_000"}
TARGET = re.compile(r"target: x ([-+]\d+\.\d+) y ([-+]\d+\.\d+) z ([-+]\d+\.\d+) m")


class PtyNode:
    """`ros2 run` whose terminal is a pseudo-terminal: the test types keys and reads the screen."""

    def __init__(self, package: str, executable: str, params: dict, log_dir: Path):
        params_file = log_dir / f"{executable}_params.yaml"
        params_file.write_text(yaml.safe_dump({"/**": {"ros__parameters": params}}))
        self._master, slave = os.openpty()
        self.proc = subprocess.Popen(["ros2", "run", package, executable, "--ros-args", "--params-file", str(params_file)],
                                     stdin=slave, stdout=slave, stderr=slave, start_new_session=True)
        os.close(slave)
        self._lock = threading.Lock()
        self._screen = ""
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        while True:
            try:
                data = os.read(self._master, 4096)
            except OSError:  # the node exited: the pty's other side closed
                return
            if not data:
                return
            with self._lock:
                self._screen += data.decode("utf-8", errors="replace")

    @property
    def screen(self) -> str:
        with self._lock:
            return self._screen

    def type(self, keys: str) -> None:
        os.write(self._master, keys.encode())

    def shows(self, text: str, since: int = 0, timeout: float = 30.0) -> bool:
        return wait_for(lambda: text in self.screen[since:], timeout)

    def stop(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait()
        os.close(self._master)


class Topics:
    """What the teleop puts on the graph, and where the arm is."""

    def __init__(self, node) -> None:
        from actaim2_msgs.msg import EpisodeEvent, InteractionMode, Keypose
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        latched = dict(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.episodes, self.modes, self.keyposes, self.joints = [], [], [], {}
        node.create_subscription(EpisodeEvent, "/episode", self.episodes.append, QoSProfile(depth=10, **latched))
        node.create_subscription(InteractionMode, "/interaction_mode", self.modes.append, QoSProfile(depth=10, **latched))
        self.keypose_sub = node.create_subscription(Keypose, "/keypose", self.keyposes.append,
                                                     QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        node.create_subscription(JointState, "/joint_states", lambda m: self.joints.update(zip(m.name, m.position)), 10)


def last_target(screen: str) -> np.ndarray:
    return np.array([float(v) for v in TARGET.findall(screen)[-1]])


def test_keyboard_teleop_through_a_pseudo_terminal(start_node, ros_node, tmp_path):
    panda = RobotModel(load_robot_spec("panda"))
    topics = Topics(ros_node)
    start_node("actaim2_sim", "sim_node", SIM_PARAMS)
    control = start_node("actaim2_control", "control_node", {})
    teleop = PtyNode("actaim2_control", "teleop_node", TELEOP_PARAMS, tmp_path)
    try:
        assert teleop.shows("actaim2 teleop: keys", timeout=90.0), teleop.screen + control.output()
        assert teleop.shows("target: x"), teleop.screen
        assert "w/s  forward/back" in teleop.screen and "0 INIT" in teleop.screen  # the key map

        teleop.type("e")
        assert teleop.shows("episode 0 started"), teleop.screen
        mark = len(teleop.screen)
        teleop.type("m")
        assert teleop.shows("mode label (1 push", mark), teleop.screen
        teleop.type("2\r")
        assert teleop.shows("mode label 'pull' published", mark), teleop.screen

        start = last_target(teleop.screen)
        for _ in range(3):  # 2 cm forward each, 0.1 s apart at the 0.2 m/s bound: none dropped
            teleop.type("w")
            time.sleep(0.3)
        assert wait_for(lambda: len(TARGET.findall(teleop.screen)) >= 4, 10.0), teleop.screen
        target = last_target(teleop.screen)
        np.testing.assert_allclose(target - start, [0.06, 0.0, 0.0], atol=1.5e-3)  # printed with 1 mm resolution

        def tcp() -> np.ndarray:
            if not set(panda.joint_names) <= set(topics.joints):
                return np.full(3, np.inf)
            return panda.fk(np.array([topics.joints[j] for j in panda.joint_names]))[:3, 3]

        assert wait_for(lambda: np.linalg.norm(tcp() - target) < 3e-3, 10.0), (tcp(), target)  # the arm followed

        assert wait_for(matched(topics.keypose_sub), 30.0), control.output()[-2000:]
        mark = len(teleop.screen)
        teleop.type("3")
        assert teleop.shows("MANIPULATE not marked: the next keypose is INIT", mark), teleop.screen
        for key, name in (("0", "INIT"), ("1", "REACH"), ("2", "GRASP"), ("3", "MANIPULATE")):
            mark = len(teleop.screen)
            teleop.type(key)
            assert teleop.shows(f"{name} executed", mark, timeout=60.0), teleop.screen[mark:] + control.output()[-2000:]
        assert wait_for(lambda: len(topics.keyposes) == 4, 10.0), ([k.phase for k in topics.keyposes], control.output()[-3000:])
        assert [k.phase for k in topics.keyposes] == [0, 1, 2, 3]
        assert [k.gripper_closed for k in topics.keyposes] == [False, False, True, True]
        marked = np.array([[k.pose.position.x, k.pose.position.y, k.pose.position.z] for k in topics.keyposes])
        np.testing.assert_allclose(marked, np.tile(target, (4, 1)), atol=1.5e-3)

        mark = len(teleop.screen)
        teleop.type("]]")  # 8 cm steps, straight down until the table refuses them
        assert teleop.shows("jog step 80.0 mm", mark), teleop.screen
        for _ in range(12):
            teleop.type("f")
            time.sleep(0.5)
            if "refused: " in teleop.screen[mark:]:
                break
        refusal = teleop.screen[mark:].split("refused: ")[-1].splitlines()[0]
        assert "collision" in refusal, teleop.screen[mark:]
        assert "clipped to" in teleop.screen[mark:], teleop.screen[mark:]

        mark = len(teleop.screen)
        teleop.type("y")
        assert teleop.shows("episode 0 ended: SUCCESS", mark), teleop.screen
        teleop.type("q")
        assert teleop.proc.wait(timeout=15) == 0, teleop.screen
        assert "bye" in teleop.screen
    finally:
        teleop.stop()
    assert wait_for(lambda: len(topics.episodes) == 2, 10.0)
    start_event, end_event = topics.episodes
    assert (start_event.event, start_event.episode, start_event.object_id) == (0, 0, "table_000")
    assert (end_event.event, end_event.success, end_event.object_id) == (1, True, "table_000")
    assert [m.label for m in topics.modes][-1] == "pull" and topics.modes[-1].cluster == -1


def test_teleop_node_needs_a_terminal():
    done = subprocess.run(["ros2", "run", "actaim2_control", "teleop_node"], stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "standard input is not a terminal" in done.stderr + done.stdout, done
