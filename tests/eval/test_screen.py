"""The plan-screened ActAIM2 row's look-ahead: the real planner (Pinocchio IK, coal collisions) judges INIT and REACH."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.control.collision import CollisionChecker
from actaim2.control.ik import IKSolver
from actaim2.control.model import RobotModel
from actaim2.control.planner import KeyposePlanner
from actaim2.eval.screen import PlanScreen
from actaim2.geometry import matrix_to_pose
from actaim2.keypose import INIT, REACH, Keypose
from actaim2.robots import load_robot_spec

# tcp pointing forward (+x) at a handle 0.6 m ahead; INIT 12 cm behind it on the approach axis
FORWARD = np.column_stack([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
P1 = np.array([0.6, 0.0, 0.6])


def keypose(phase: int, position) -> Keypose:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = FORWARD, position
    p, q = matrix_to_pose(T)
    return Keypose(phase, p, q, False)


@pytest.fixture(scope="module")
def screen() -> PlanScreen:
    robot = RobotModel(load_robot_spec("panda"))
    checker = CollisionChecker(robot)
    return PlanScreen(KeyposePlanner(robot, checker, IKSolver(robot, checker)), robot.spec.home, 12)


def predictor(init, reach):
    asked = []

    def predict(phase: int, closed: bool) -> Keypose:
        asked.append((phase, closed))
        return keypose(phase, init if phase == INIT else reach)

    return predict, asked


def test_reachable_init_and_reach_pass(screen) -> None:
    predict, asked = predictor(P1 - 0.12 * FORWARD[:, 2], P1)
    screen.planner.set_cloud(None)
    assert screen.refusal(predict, np.random.default_rng(0)) is None
    assert asked == [(INIT, False), (REACH, False)]


def test_the_first_refused_phase_ends_the_look_ahead(screen) -> None:
    rng = np.random.default_rng(0)
    screen.planner.set_cloud(None)
    predict, asked = predictor([2.5, 0.0, 0.6], P1)  # INIT out of reach: REACH is not even predicted
    assert screen.refusal(predict, rng).startswith("IK for") and asked == [(INIT, False)]
    predict, asked = predictor(P1 - 0.12 * FORWARD[:, 2], [2.5, 0.0, 0.6])  # INIT plans, REACH out of reach
    assert screen.refusal(predict, rng).startswith("IK for [2.5") and asked == [(INIT, False), (REACH, False)]


def test_draw_seeds_start_with_the_samples_own() -> None:
    seeds = [PlanScreen.draw_seed(2**31 + 7, d) for d in range(12)]
    assert seeds[0] == 2**31 + 7  # draw 0 is the unscreened row's sample
    assert len(set(seeds)) == 12 and all(0 <= s < 2**63 for s in seeds)
    assert seeds == [PlanScreen.draw_seed(2**31 + 7, d) for d in range(12)]  # reproducible
