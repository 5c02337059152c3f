"""GripperCommand goal outcomes (actaim2.sim.gripper_action), without ROS: stalls are judged on
position progress over a window, never on one velocity sample."""
from __future__ import annotations

import numpy as np

from actaim2.sim.gripper_action import GripperGoal

RATE = 50.0  # Hz, the sim node's default monitor rate


def run(positions, target: float = 0.0, allow_stalling: bool = True):
    """Feed ``positions`` (one per monitor period) to a goal with the node's default thresholds
    (stall below 1 mm/s mean over 1 s); return (time, outcome) of the first outcome, or None."""
    goal = GripperGoal(target, 0.0, positions[0], goal_tolerance=0.002, stall_velocity=0.001, stall_timeout=1.0,
                       allow_stalling=allow_stalling)
    for k, position in enumerate(positions[1:], start=1):
        outcome = goal.update(k / RATE, float(position))
        if outcome is not None:
            return k / RATE, outcome
    return None


def test_squeezing_a_handle_with_jitter_stalls_after_one_window():
    rng = np.random.default_rng(0)
    closing = np.linspace(0.04, 0.006, 10)  # 0.18 s of travel, then the fingers sit on the handle
    # sample-to-sample jitter of 30 um (1.5 mm/s as a two-sample speed), no progress
    squeezing = 0.006 + rng.uniform(-15e-6, 15e-6, size=150)
    ended = run(np.concatenate([closing, squeezing]))
    assert ended is not None
    t, outcome = ended
    assert outcome.stalled and outcome.succeeded and not outcome.reached_goal
    stopped = (len(closing) - 1) / RATE
    assert 1.0 - 1e-9 <= t - stopped <= 1.1, t  # one window after the fingers stopped


def test_slow_progress_is_not_a_stall_and_reaching_the_target_is():
    slow = np.linspace(0.04, 0.0, int(20 * RATE))  # 2 mm/s for 20 s: moving, though slowly
    t, outcome = run(slow)
    assert outcome.reached_goal and outcome.succeeded and not outcome.stalled
    assert t > 18.9  # only where the target tolerance begins


def test_a_stall_aborts_unless_stalling_is_allowed():
    blocked = np.full(100, 0.01)
    _, outcome = run(blocked, allow_stalling=False)
    assert outcome.stalled and not outcome.succeeded
