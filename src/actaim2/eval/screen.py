"""The look-ahead screen of a policy sample: redraw the mode while the planner refuses its first two keyposes.

Data Collection's samplers draw until an action passes an IK screen (``collect.ik_reachable``),
so every sample it executes is reachable. A policy sample can be screened the same way without
privilege: the views are robot-hidden, so the views the predictor reads at INIT and at REACH are
those of the scene before the arm moves (as long as INIT touches nothing). The screen predicts
INIT and REACH from the initial views for a drawn eps, plans INIT from home and REACH from
INIT's goal with the evaluation's own planner (IK, collisions with the object cloud, the
straight REACH line), and accepts the first eps whose two motions both plan. Draw 0 is the
unscreened sample's own eps, so a sample that passes at once executes exactly as the
unscreened row's; when no draw passes, draw 0 is executed (and fails where the planner said).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from actaim2.control.planner import KeyposePlanner, PlanningError
from actaim2.control.trajectory import State
from actaim2.geometry import pose_to_matrix
from actaim2.keypose import INIT, REACH, Keypose


@dataclass
class PlanScreen:
    planner: KeyposePlanner
    home: np.ndarray  # the arm's joint positions when a sample begins
    draws: int  # eps drawn at most (1 = no screening)

    @staticmethod
    def draw_seed(sample_seed: int, draw: int) -> int:
        """The selector's seed of draw ``draw``: the sample's own seed first, then independent ones."""
        if draw == 0:
            return int(sample_seed)
        return int(np.random.SeedSequence((int(sample_seed), draw)).generate_state(1, np.uint64)[0] >> 1)

    def refusal(self, predict: Callable[[int, bool], Keypose], rng: np.random.Generator) -> str | None:
        """Why the planner refuses INIT or REACH of ``predict`` ((phase, gripper closed) -> keypose); None: both plan."""
        init = predict(INIT, False)
        try:
            motion = self.planner.plan(INIT, pose_to_matrix(init.position, init.quat_xyzw), bool(init.gripper_closed),
                                       State.at_rest(self.home), rng=rng)
            at_init = motion.trajectory.positions[-1] if motion.trajectory is not None else self.home
            reach = predict(REACH, bool(init.gripper_closed))
            self.planner.plan(REACH, pose_to_matrix(reach.position, reach.quat_xyzw), bool(reach.gripper_closed),
                              State.at_rest(at_init), rng=rng)
        except PlanningError as exc:
            return str(exc)
        return None
