"""From a keypose and the arm's current state to a gripper command and a joint trajectory.

The four phases of the primitive (DESIGN.md) plan differently:
  * INIT: one Ruckig joint-space segment to an IK solution of p0.
  * REACH: the arm arrives along the approach axis (tcp z) on a straight line ending at p1.
    When the tcp already lies on that axis behind p1 (the usual case: p0 is put there) and the
    arm can follow it from where it is, the whole motion is that line; otherwise IK solves p1
    first (with restarts), the line is walked back from there to the pre-grasp pose
    ``approach_distance`` behind p1, a Ruckig segment reaches that via point and the line
    follows, chained with a chosen speed along the line so the arm does not stop there.
  * GRASP: no arm motion; the gripper closes.
  * MANIPULATE: a straight line from the current tcp pose to p2 (orientation kept).
With ``hand_half_turn``, a pose and its half turn about the approach axis count as one goal (a
two-finger hand grasps the same either way, and the policy's rotation targets keep one of the
pair, while data collection executed both): INIT plans the pose as given and its half turn if that
is refused; REACH and MANIPULATE plan the one nearer the tcp's current orientation (so they follow
an INIT executed half-turned), REACH the other if that is refused. MANIPULATE never turns: the
hand holds the part.
Straight lines start from rest (the arm has settled after the previous keypose).
Every sampled configuration is checked for self- and environment collisions; the fused
cloud is used only while the scene is static (INIT, REACH): during MANIPULATE the object
moves with the hand. Pure library code: executing the plan is an executor's job.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.control.collision import CollisionChecker, points_away_from
from actaim2.control.ik import IKSolver
from actaim2.control.line import LineError, LineSegment, solve_line
from actaim2.control.model import RobotModel
from actaim2.control.trajectory import (
    JointPlanner,
    JointTrajectory,
    Limits,
    Segment,
    State,
    TrajectoryError,
    sample,
)
from actaim2.keypose import GRASP, INIT, MANIPULATE, PHASE_NAMES, REACH, check_phase
from actaim2.profiling import timed


@dataclass(frozen=True)
class PlannerOptions:
    approach_distance: float = 0.10  # m: length of REACH's straight last segment when the arm starts off-axis
    on_axis_tolerance: float = 0.003  # m (and 2 deg): the tcp counts as on the approach axis
    line_step: float = 0.005  # m between IK samples along a straight line
    max_joint_step: float = 0.2  # rad: a larger jump between line samples refuses the line
    via_speed_fraction: float = 0.5  # speed at the pre-grasp via point, fraction of the line's top speed
    sample_period: float = 0.02  # s between trajectory points sent to the controller
    cloud_clearance: float = 0.12  # m: cloud points this close to p1 are the grasped part, not obstacles
    hand_half_turn: bool = False  # plan T or T Rz(180), whichever is accepted (order: module docstring)


# How a learned policy's keyposes are planned (the evaluation, control_node): with the half turn (a
# two-finger grasp T and T Rz(180) are the same grasp; why it is on: docs/decisions.md). The
# dataclass default stays off: data collection plans and labels exactly the pose its sampler drew.
POLICY_PLANNER = PlannerOptions(hand_half_turn=True)


@dataclass
class Motion:
    """What executing one keypose takes: a gripper command, then an arm trajectory (either may be None)."""

    phase: int
    T_goal: np.ndarray  # requested tcp pose (world)
    gripper_closed: bool | None
    trajectory: JointTrajectory | None
    line_deviation: float | None = None  # m, largest tcp distance from the straight part (when there is one)


class PlanningError(RuntimeError):
    """A keypose that cannot be executed; ``reason`` is machine-readable (an IKFailure value,
    also for collisions along the trajectory, "straight_line", "trajectory" or "invalid"),
    the message says the details."""

    def __init__(self, reason: str, message: str):
        super().__init__(message)
        self.reason = reason


class KeyposePlanner:
    """Plans keyposes for one robot in one workspace (not thread-safe: shared Pinocchio data)."""

    def __init__(self, robot: RobotModel, checker: CollisionChecker, ik: IKSolver, options: PlannerOptions = PlannerOptions()):
        self.robot = robot
        self.checker = checker
        self.ik = ik
        self.options = options
        self._joint_planner = JointPlanner(robot.n)
        self._cloud: np.ndarray | None = None

    def set_cloud(self, points: np.ndarray | None) -> None:
        """Latest obstacle cloud in `world` (None: none); cropped around each grasp point when used."""
        self._cloud = None if points is None else np.asarray(points, dtype=float)

    @timed("planning")
    def plan(self, phase: int, T_goal: np.ndarray, gripper_closed: bool, start: State, velocity_scaling: float = 1.0,
             rng: np.random.Generator | None = None) -> Motion:
        """The motion executing keypose (phase, T_goal, gripper_closed) from the arm state ``start``."""
        try:
            phase = check_phase(phase)
        except ValueError as exc:
            raise PlanningError("invalid", str(exc)) from None
        T_goal = np.asarray(T_goal, dtype=float)
        if phase == GRASP:
            return Motion(phase, T_goal, gripper_closed, None)
        if not self.options.hand_half_turn:
            return self._plan_pose(phase, T_goal, gripper_closed, start, velocity_scaling, rng)
        first, second = self._half_turn_order(T_goal, start.position, phase)
        if phase == MANIPULATE:  # the hand holds the part: turning it half a turn on the way is no option
            return self._plan_pose(phase, first, gripper_closed, start, velocity_scaling, rng)
        try:
            return self._plan_pose(phase, first, gripper_closed, start, velocity_scaling, rng)
        except PlanningError as refused:
            try:
                return self._plan_pose(phase, second, gripper_closed, start, velocity_scaling, rng)
            except PlanningError:
                raise refused from None  # the nearer pose's reason: what a user asked for, nearly

    def _half_turn_order(self, T_goal: np.ndarray, angles: np.ndarray, phase: int) -> tuple[np.ndarray, np.ndarray]:
        """(T_goal, T_goal Rz(180)) in the order to try: as given at INIT, else the one whose orientation is
        nearer the tcp's at ``angles`` first."""
        turned = T_goal.copy()
        turned[:3, :2] *= -1.0  # Rz(180): tcp x and y reversed, approach axis and position kept
        if phase == INIT:
            return T_goal, turned
        R_now = self.robot.fk(angles)[:3, :3]
        distance = [Rotation.from_matrix(R_now.T @ T[:3, :3]).magnitude() for T in (T_goal, turned)]
        return (T_goal, turned) if distance[0] <= distance[1] else (turned, T_goal)

    def _plan_pose(self, phase: int, T_goal: np.ndarray, gripper_closed: bool, start: State, velocity_scaling: float,
                   rng: np.random.Generator | None) -> Motion:
        """The motion to exactly ``T_goal`` (INIT, REACH or MANIPULATE)."""
        limits = Limits.of(self.robot, velocity_scaling)
        use_cloud = phase != MANIPULATE and self._cloud is not None
        self.checker.set_cloud(points_away_from(self._cloud, T_goal[:3, 3], self.options.cloud_clearance) if use_cloud else None)
        try:
            if phase == INIT:
                segments, deviation = [self._joint_segment(start, self._ik(T_goal, start.position, rng), limits)], None
            elif phase == REACH:
                segments, deviation = self._reach(T_goal, start, limits, rng)
            else:
                segments, deviation = self._line_from(start.position, T_goal, limits)
        except LineError as exc:
            raise PlanningError("straight_line", f"{PHASE_NAMES[phase]}: straight line refused: {exc}") from exc
        except TrajectoryError as exc:
            raise PlanningError("trajectory", f"{PHASE_NAMES[phase]}: {exc}") from exc
        trajectory = sample(segments, self.robot.joint_names, self.options.sample_period) if segments else None
        if trajectory is not None and len(trajectory) == 0:
            trajectory = None  # already at the goal
        if trajectory is not None:
            self._check_path(trajectory, phase, use_cloud)
        return Motion(phase, T_goal, gripper_closed, trajectory, deviation)

    def _ik(self, T: np.ndarray, seed: np.ndarray, rng: np.random.Generator | None) -> np.ndarray:
        result = self.ik.solve(T, seed, rng=rng)
        if not result.success:
            raise PlanningError(result.failure.value, f"IK for {np.round(T[:3, 3], 3).tolist()}: {result.message}")
        return result.angles

    def _joint_segment(self, start: State, goal: np.ndarray, limits: Limits, goal_state: State | None = None) -> Segment:
        return self._joint_planner.plan(start, goal_state or State.at_rest(goal), limits)

    def _reach(self, T_goal: np.ndarray, start: State, limits: Limits, rng) -> tuple[list[Segment], float]:
        opts = self.options
        T_now = self.robot.fk(start.position)
        approach = T_goal[:3, 2]
        behind = T_goal[:3, 3] - T_now[:3, 3]
        lateral = np.linalg.norm(behind - (behind @ approach) * approach)
        turn = Rotation.from_matrix(T_now[:3, :3].T @ T_goal[:3, :3]).magnitude()
        if behind @ approach >= 0.0 and lateral <= opts.on_axis_tolerance and turn <= np.radians(2.0):
            try:
                return self._line_from(start.position, T_goal, limits)
            except LineError:
                pass  # the arm's current branch runs into a limit on the way: come in on another one
        goal = self._ik(T_goal, start.position, rng)
        T_pre = T_goal.copy()
        T_pre[:3, 3] -= opts.approach_distance * approach
        path = solve_line(self.ik, T_pre, T_goal, goal, anchor_at_end=True, step=opts.line_step,
                          max_joint_step=opts.max_joint_step, use_cloud=self.checker.has_cloud)
        line = LineSegment(path, limits, entry_speed_fraction=opts.via_speed_fraction)
        via = line.entry_state()
        return [self._joint_segment(start, via.position, limits, via), line], path.deviation(self.robot)[0]

    def _line_from(self, angles: np.ndarray, T_goal: np.ndarray, limits: Limits) -> tuple[list[Segment], float]:
        """A straight tcp line from where the joints ``angles`` put it to ``T_goal``."""
        opts = self.options
        T_start = self.robot.fk(angles)
        if np.linalg.norm(T_goal[:3, 3] - T_start[:3, 3]) < 1e-4 and Rotation.from_matrix(T_start[:3, :3].T @ T_goal[:3, :3]).magnitude() < 1e-3:
            return [], 0.0  # already there
        path = solve_line(self.ik, T_start, T_goal, angles, anchor_at_end=False, step=opts.line_step,
                          max_joint_step=opts.max_joint_step, use_cloud=self.checker.has_cloud)
        return [LineSegment(path, limits)], path.deviation(self.robot)[0]

    def _check_path(self, trajectory: JointTrajectory, phase: int, use_cloud: bool) -> None:
        for t, q in zip(trajectory.times, trajectory.positions):
            hit = self.checker.check(q, use_cloud=use_cloud)
            if hit is not None:
                reason = "self_collision" if hit.kind == "self" else "environment_collision"
                raise PlanningError(reason, f"{PHASE_NAMES[phase]}: {hit} at t = {t:.2f} s of the trajectory")
