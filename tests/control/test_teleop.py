"""The keyboard teleop's rules without a terminal: jogging checked by control_node's IK at a bounded
speed (clipped or refused with IK's reason), marking the four keyposes in order, labels, episodes."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.control.collision import CollisionChecker, Workspace
from actaim2.control.ik import IKOptions, IKSolver
from actaim2.control.model import RobotModel
from actaim2.control.teleop import (
    AskLabel,
    End,
    Gripper,
    Jog,
    JogSettings,
    Label,
    Mark,
    Message,
    Quit,
    Start,
    TeleopSession,
)
from actaim2.geometry import rotation_angle
from actaim2.keypose import GRASP, INIT, MANIPULATE, REACH
from actaim2.robots import load_robot_spec

SETTINGS = JogSettings(translation_step=0.01, rotation_step=np.radians(5.0), max_speed=0.05,
                       max_angular_speed=np.radians(30.0))


@pytest.fixture(scope="module")
def panda():
    robot = RobotModel(load_robot_spec("panda"))
    solver = IKSolver(robot, CollisionChecker(robot, Workspace()), IKOptions(restarts=0))
    return robot, solver


def session(panda, settings: JogSettings = SETTINGS) -> TeleopSession:
    robot, solver = panda
    s = TeleopSession(solver.solve, robot.fk, robot.spec.max_velocity, settings)
    s.sync(robot.spec.home)
    return s


def test_jogs_move_the_target_along_world_axes_and_turn_it_about_its_own(panda):
    robot, _ = panda
    s = session(panda)
    start = s.target.copy()
    t = 0.0
    for key, axis, sign in (("w", 0, 1), ("a", 1, 1), ("f", 2, -1)):
        jog = s.press(key, t)
        assert isinstance(jog, Jog) and jog.note == ""
        expected = start[:3, 3].copy()
        expected[axis] += 0.01 * sign
        np.testing.assert_allclose(jog.T[:3, 3], expected, atol=1e-9)
        np.testing.assert_allclose(robot.fk(jog.joints)[:3, 3], expected, atol=2e-4)  # IK's answer reaches it
        assert jog.duration >= 0.01 / SETTINGS.max_speed - 1e-12
        start, t = jog.T.copy(), t + jog.duration
    turn = s.press("j", t)  # about the approach axis: the position stays, the approach axis too
    assert isinstance(turn, Jog)
    np.testing.assert_allclose(turn.T[:3, 3], start[:3, 3], atol=1e-12)
    np.testing.assert_allclose(turn.T[:3, 2], start[:3, 2], atol=1e-12)
    assert rotation_angle(turn.T[:3, :3], start[:3, :3]) == pytest.approx(np.radians(5.0))
    assert turn.duration >= np.radians(5.0) / SETTINGS.max_angular_speed - 1e-12


def test_a_held_key_moves_the_target_at_the_speed_bound(panda):
    s = session(panda)
    start = s.target[:3, 3].copy()
    times = [k / 30.0 for k in range(60)]  # 30 Hz auto-repeat for 2 s
    effects = [s.press("s", t) for t in times]
    applied = [(t, e) for t, e in zip(times, effects) if e is not None]
    moved = np.linalg.norm(s.target[:3, 3] - start)
    assert moved <= SETTINGS.max_speed * 2.0 + 0.01 + 1e-9  # never faster than the bound (plus the step under way)
    assert moved >= 0.05  # ... and it does move: a step every step duration
    for (t0, jog), (t1, _) in zip(applied, applied[1:]):
        assert isinstance(jog, Jog) and t1 >= t0 + jog.duration  # keys during a step were dropped


def test_unreachable_targets_are_clipped_then_refused_with_the_reason(panda):
    s = session(panda, JogSettings(translation_step=0.08, max_speed=100.0))
    notes, refusal, t = [], None, 0.0
    for _ in range(40):  # straight down from home: the table (z = 0) stops the hand
        effect = s.press("f", t)
        t += 10.0
        if isinstance(effect, Message):
            refusal = effect.text
            break
        assert isinstance(effect, Jog)
        notes.append(effect.note)
    assert any(n.startswith("clipped to") for n in notes), notes
    assert refusal is not None and refusal.startswith("refused: ") and "collision" in refusal, refusal
    assert s.target[2, 3] > 0.0  # the target stayed where the arm can go
    far = session(panda, JogSettings(translation_step=0.5, max_speed=100.0))
    clipped = far.press("w", 0.0)  # 0.5 m forward: out of reach, only a part of the step is taken
    assert isinstance(clipped, Jog) and clipped.note.startswith("clipped to") and "unreachable" in clipped.note, clipped
    assert "unreachable" in session(panda, JogSettings(translation_step=1.0)).press("w", 0.0).text  # none of it


def test_a_jog_to_another_arm_configuration_is_refused(panda):
    s = session(panda, JogSettings(max_joint_step=1e-4))
    effect = s.press("w", 0.0)
    assert isinstance(effect, Message) and "another arm configuration" in effect.text


def test_keyposes_are_marked_in_order_inside_an_episode(panda):
    s = session(panda)
    assert "start an episode first" in s.press("0", 0.0).text
    assert isinstance(s.press("m", 0.0), AskLabel)
    assert "published when the next episode starts" in s.set_label("2").text and s.label == "pull"
    start = s.press("e", 0.0)
    assert start == Start(0, "pull")
    assert "is running" in s.press("e", 0.0).text
    assert "next keypose is INIT" in s.press("2", 0.0).text
    marks = []
    for key, phase in (("0", INIT), ("1", REACH), ("2", GRASP), ("3", MANIPULATE)):
        mark = s.press(key, 0.0)
        assert isinstance(mark, Mark) and mark.keypose.phase == phase
        np.testing.assert_allclose(mark.keypose.position, s.target[:3, 3])
        if phase == REACH:  # execution failed: the same phase is marked again
            s.marked(mark.keypose, executed=False)
            assert "next keypose is GRASP" not in s.press("2", 0.0).text
            mark = s.press(key, 0.0)
        s.marked(mark.keypose, executed=True)
        marks.append(mark.keypose)
    assert [k.gripper_closed for k in marks] == [False, False, True, True]
    assert "all four keyposes are marked" in s.press("0", 0.0).text
    assert s.set_label("push the top drawer") == Label("push the top drawer")
    end = s.press("y", 0.0)
    assert isinstance(end, End) and end.success and end.episode == 0 and "not marked" not in end.note
    assert s.press("e", 0.0) == Start(1, "push the top drawer")
    end = s.press("n", 0.0)
    assert isinstance(end, End) and not end.success and "not marked: INIT, REACH, GRASP, MANIPULATE" in end.note


def test_other_keys(panda):
    s = session(panda)
    assert s.press("g", 0.0) == Gripper(closed=True) and s.press("h", 0.0) == Gripper(closed=False)
    assert "5.0 mm" in s.press("[", 0.0).text
    z = s.target[2, 3]
    assert s.press("r", 0.0).T[2, 3] == pytest.approx(z + 0.005)
    assert "w/s" in s.press("?", 0.0).text and "target: x" in s.press("t", 0.0).text
    assert s.press("x", 0.0) is None
    assert s.press("q", 0.0) == Quit(None)
    s.press("e", 0.0)
    quit_ = s.press("q", 0.0)
    assert isinstance(quit_, Quit) and quit_.end is not None and not quit_.end.success and "operator quit" in quit_.end.note
