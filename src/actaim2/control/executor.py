"""Running keyposes: plan with :class:`KeyposePlanner`, execute through a pluggable executor.

The executor is whatever moves the arm: the control node's ROS action clients
(FollowJointTrajectory, GripperCommand) or :class:`actaim2.rollout.sim_executor.SimEnvExecutor`
calling the simulator directly for data collection. It only needs the three methods of
:class:`Executor`; everything else (phases, gripper bookkeeping, errors) lives here, once.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Protocol, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.control.planner import KeyposePlanner, Motion, PlanningError
from actaim2.control.trajectory import JointTrajectory, State
from actaim2.geometry import pose_to_matrix
from actaim2.keypose import GRASP, INIT, MANIPULATE, PHASE_NAMES, REACH, Keypose

Feedback = Callable[[int, float], None]  # (phase, progress 0..1)


@dataclass(frozen=True)
class StepResult:
    success: bool
    message: str


class Executor(Protocol):
    def arm_state(self) -> State:
        """Current arm joint angles (RobotSpec.arm_joints order) and velocities."""

    def follow(self, trajectory: JointTrajectory, on_progress: Callable[[float], None]) -> StepResult:
        """Execute the trajectory (points after the current state); return when done or failed."""

    def set_gripper(self, closed: bool) -> StepResult:
        """Open or close; a gripper stalled on an object counts as success."""


@dataclass(frozen=True)
class Outcome:
    """Result of one keypose, as ExecuteKeypose's result carries it."""

    success: bool
    message: str
    position_error: float  # m between the reached and the requested tcp position
    orientation_error: float  # rad
    reason: str = ""  # machine-readable failure reason ("" on success)
    refused: str = ""  # executed a fallback: why the planner refused each candidate before it (a log says it)


class KeyposeRunner:
    """Executes keyposes in the order they come, remembering the gripper command last sent."""

    def __init__(self, planner: KeyposePlanner, executor: Executor, rng: np.random.Generator | None = None):
        self.planner = planner
        self.executor = executor
        self.rng = rng if rng is not None else np.random.default_rng()
        self._gripper_closed: bool | None = None  # unknown until the first command

    def run(self, keypose: Keypose, velocity_scaling: float = 1.0, feedback: Feedback | None = None) -> Outcome:
        """Gripper first (open before moving in, close for GRASP), then the arm."""
        return self.run_first([keypose], velocity_scaling, feedback)[0]

    def run_first(self, candidates: Sequence[Keypose], velocity_scaling: float = 1.0,
                  feedback: Feedback | None = None) -> tuple[Outcome, int]:
        """Execute the first of ``candidates`` the planner accepts (a policy's keypose, then its
        fallbacks); (its outcome, its index). Nothing moves for a refused one. An executed fallback's
        ``refused`` names every candidate refused before it with the planner's reason, so a log can say
        why the keypose and the earlier fallbacks were not run. When all are refused: the first one's
        refusal (what was asked for) and index -1."""
        if not candidates:
            raise ValueError("no keypose to run")
        start, first_refusal, refusals = self._start_state(), None, []
        for index, keypose in enumerate(candidates):
            T_goal = pose_to_matrix(keypose.position, keypose.quat_xyzw)
            try:
                motion = self.planner.plan(int(keypose.phase), T_goal, bool(keypose.gripper_closed),
                                           start, velocity_scaling, self.rng)
            except PlanningError as exc:
                first_refusal = first_refusal or self._outcome(T_goal, False, str(exc), exc.reason)
                refusals.append(f"{'keypose' if index == 0 else f'alternatives[{index - 1}]'}: {exc}")
                continue
            outcome = self._execute(motion, feedback)
            return replace(outcome, refused="; ".join(refusals)), index
        return first_refusal, -1

    def _execute(self, motion: Motion, feedback: Feedback | None) -> Outcome:
        report = feedback or (lambda phase, progress: None)
        T_goal = motion.T_goal  # the pose planned: with the planner's hand_half_turn, possibly the half-turned one
        report(motion.phase, 0.0)
        if motion.gripper_closed is not None and motion.gripper_closed != self._gripper_closed:
            step = self.executor.set_gripper(motion.gripper_closed)
            if not step.success:
                self._gripper_closed = None
                return self._outcome(T_goal, False, f"{PHASE_NAMES[motion.phase]}: gripper: {step.message}", "gripper")
            self._gripper_closed = motion.gripper_closed
        if motion.trajectory is not None:
            step = self.executor.follow(motion.trajectory, lambda progress: report(motion.phase, progress))
            if not step.success:
                return self._outcome(T_goal, False, f"{PHASE_NAMES[motion.phase]}: arm: {step.message}", "execution")
        report(motion.phase, 1.0)
        return self._outcome(T_goal, True, f"{PHASE_NAMES[motion.phase]} done")

    def run_primitive(self, keyposes: Sequence[Keypose], velocity_scaling: float = 1.0,
                      feedback: Feedback | None = None) -> list[Outcome]:
        """The four-phase primitive INIT -> REACH -> GRASP -> MANIPULATE; stops at the first failure."""
        phases = [int(k.phase) for k in keyposes]
        if phases != [INIT, REACH, GRASP, MANIPULATE]:
            raise ValueError(f"the primitive needs keyposes of phases [0, 1, 2, 3] in order, got {phases}")
        outcomes = []
        for keypose in keyposes:
            outcomes.append(self.run(keypose, velocity_scaling, feedback))
            if not outcomes[-1].success:
                break
        return outcomes

    def _start_state(self) -> State:
        """Where the arm is; velocities below sensor noise count as rest."""
        state = self.executor.arm_state()
        moving = np.abs(state.velocity).max(initial=0.0) > 0.02
        return State(state.position, state.velocity if moving else np.zeros_like(state.velocity), np.zeros_like(state.position))

    def _outcome(self, T_goal: np.ndarray, success: bool, message: str, reason: str = "") -> Outcome:
        T = self.planner.robot.fk(self.executor.arm_state().position)
        position_error = float(np.linalg.norm(T[:3, 3] - T_goal[:3, 3]))
        orientation_error = float(Rotation.from_matrix(T[:3, :3].T @ T_goal[:3, :3]).magnitude())
        return Outcome(success, message, position_error, orientation_error, reason)
