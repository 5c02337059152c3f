"""Straight lines of the tcp: dense IK along the line, then a time-optimal timing along it.

The last segment of REACH and the whole of MANIPULATE must keep the tcp on a straight line,
so the gripper meets a handle head-on and pulls along the motion. The line (position
linear, orientation slerp) is sampled every few millimetres and solved by IK, each sample
seeded with its neighbour's solution and no restarts, so the arm stays on one branch; a
jump between neighbours means the line crosses a singularity or a limit and is refused.
A cubic spline q(u), u in [0, 1], through the solutions gives a C2 joint path.

Timing is a 1-DoF Ruckig profile on u, time-optimal and jerk-limited. Its limits come from
the joint limits through the path derivatives q'(u), q''(u), q'''(u):
joint velocity q' u_dot, acceleration q'' u_dot^2 + q' u_ddot, jerk
q''' u_dot^3 + 3 q'' u_dot u_ddot + q' u_dddot. Each term first gets a share of the joint
limit; the u limits are then scaled to the largest factor whose sampled timing keeps every
joint within its limits.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation, Slerp

from actaim2.control.ik import IKSolver
from actaim2.control.model import RobotModel
from actaim2.control.trajectory import Limits, State, TrajectoryError


class LineError(RuntimeError):
    """The straight line cannot be followed (IK failure, collision or jump along it)."""


@dataclass
class LinePath:
    """IK solutions along a straight tcp line and the joint spline through them."""

    T_start: np.ndarray
    T_goal: np.ndarray
    u: np.ndarray  # (K,) sample parameters, 0 .. 1
    angles: np.ndarray  # (K, n) joint angles at the samples
    spline: CubicSpline

    def state(self, u: float, u_dot: float = 0.0, u_ddot: float = 0.0) -> State:
        """Joint state at path parameter u moving along the path at u_dot, u_ddot."""
        d1, d2 = self.spline(u, 1), self.spline(u, 2)
        return State(self.spline(u), d1 * u_dot, d2 * u_dot**2 + d1 * u_ddot)

    def deviation(self, robot: RobotModel, samples_per_interval: int = 4) -> tuple[float, float]:
        """Largest distance (m) of the tcp from the line and angle (rad) from the slerped
        orientation, along the spline between and at the IK samples."""
        u = np.linspace(0.0, 1.0, samples_per_interval * (len(self.u) - 1) + 1)
        a, b = self.T_start[:3, 3], self.T_goal[:3, 3]
        ab = b - a
        length2 = float(ab @ ab)
        rotations = _slerp(self.T_start, self.T_goal)(u).as_matrix()
        worst_pos = worst_rot = 0.0
        for qk, Rk in zip(self.spline(u), rotations):
            T = robot.fk(qk)
            p = T[:3, 3]
            s = np.clip((p - a) @ ab / length2, 0.0, 1.0) if length2 > 0 else 0.0
            worst_pos = max(worst_pos, float(np.linalg.norm(p - (a + s * ab))))
            worst_rot = max(worst_rot, float(Rotation.from_matrix(Rk.T @ T[:3, :3]).magnitude()))
        return worst_pos, worst_rot


def solve_line(
    solver: IKSolver,
    T_start: np.ndarray,
    T_goal: np.ndarray,
    anchor: np.ndarray,
    anchor_at_end: bool,
    step: float = 0.005,
    angle_step: float = np.radians(2.0),
    max_joint_step: float = 0.2,
    use_cloud: bool = False,
    max_deviation: float = 2e-4,
    refinements: int = 3,
) -> LinePath:
    """IK along the line T_start -> T_goal, walking from the anchored end (joint angles
    ``anchor``, which must be a solution there) to the other, each sample seeded by the last.

    Where the joints curve fast (near a singularity) the spline between samples can leave
    the line: samples are made denser (step halved, up to ``refinements`` times) until the
    spline stays within ``max_deviation`` (m) of it.
    Raises :class:`LineError` naming where (fraction of the line) and why it fails."""
    for _ in range(refinements):
        path = _solve_line(solver, T_start, T_goal, anchor, anchor_at_end, step, angle_step, max_joint_step, use_cloud)
        if path.deviation(solver.robot, samples_per_interval=2)[0] <= max_deviation:
            return path
        step, angle_step = 0.5 * step, 0.5 * angle_step
    return _solve_line(solver, T_start, T_goal, anchor, anchor_at_end, step, angle_step, max_joint_step, use_cloud)


def _solve_line(solver, T_start, T_goal, anchor, anchor_at_end, step, angle_step, max_joint_step, use_cloud) -> LinePath:
    robot = solver.robot
    T_anchor = robot.fk(anchor)
    if anchor_at_end:
        T_goal = T_anchor
    else:
        T_start = T_anchor
    length = float(np.linalg.norm(T_goal[:3, 3] - T_start[:3, 3]))
    angle = float(Rotation.from_matrix(T_start[:3, :3].T @ T_goal[:3, :3]).magnitude())
    k = max(2, int(np.ceil(max(length / step, angle / angle_step))))
    u = np.linspace(0.0, 1.0, k + 1)
    positions = T_start[:3, 3] + np.outer(u, T_goal[:3, 3] - T_start[:3, 3])
    rotations = _slerp(T_start, T_goal)(u).as_matrix()
    tight = IKSolver(robot, solver.checker, replace(solver.options, position_tolerance=1e-6, orientation_tolerance=1e-5, restarts=0))
    order = range(k, -1, -1) if anchor_at_end else range(k + 1)
    angles = np.empty((k + 1, robot.n))
    previous = None
    for i in order:
        if previous is None:
            angles[i] = previous = np.asarray(anchor, dtype=float)
            continue
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = rotations[i], positions[i]
        result = tight.solve(T, previous, use_cloud=use_cloud)
        where = f"at {100 * u[i]:.0f}% of the {length * 1000:.0f} mm line"
        if not result.success:
            raise LineError(f"{where}: {result.message}")
        jump = float(np.max(np.abs(result.angles - previous)))
        if jump > max_joint_step:
            raise LineError(f"{where}: the joints jump {jump:.2f} rad between samples (singularity or joint limit)")
        angles[i] = previous = result.angles
    return LinePath(T_start, T_goal, u, angles, CubicSpline(u, angles, axis=0))


class LineSegment:
    """The line path timed by a 1-DoF Ruckig profile on u within the joint limits."""

    def __init__(self, path: LinePath, limits: Limits, entry_speed_fraction: float = 0.0, margin: float = 0.99):
        """``entry_speed_fraction`` of the top speed along the line is the speed it starts with
        (0: from rest; > 0 when a segment before it arrives moving, see :meth:`entry_state`).

        The shares of :meth:`_u_limits` are conservative (the peaks of the path derivatives
        rarely coincide), so the u limits are scaled by the largest common factor whose timing
        still passes the sampled check at ``margin`` of every joint limit (a short bisection)."""
        self.path = path
        self.limits = limits
        self._margin = margin
        u = np.linspace(0.0, 1.0, 8 * (len(path.u) - 1) + 1)
        self._d1 = np.abs(path.spline(u, 1)).max(axis=0) + 1e-12
        self._d2 = np.abs(path.spline(u, 2)).max(axis=0)
        self._d3 = np.abs(path.spline(u, 3)).max(axis=0)
        base = self._u_limits()
        best, lo, hi, scale = None, 0.0, np.inf, 1.0
        for _ in range(10):
            timing = self._timing(base, scale, entry_speed_fraction)
            if timing is not None:
                best, lo = timing, scale
            else:
                hi = scale
            if hi / max(lo, 1e-12) < 1.1 or scale > 16.0:
                break
            scale = 2.0 * scale if np.isinf(hi) else (0.5 * scale if lo == 0.0 else 0.5 * (lo + hi))
        if best is None:
            raise TrajectoryError("no timing of the straight line stays within the joint limits")
        self._profile, self.start_speed, self.max_speed = best
        self.duration = float(self._profile.duration)

    def _u_limits(self) -> tuple[float, float, float]:
        """u_dot, u_ddot, u_dddot bounds giving each term of the joint derivatives its share."""
        lim, d1, d2, d3 = self.limits, self._d1, self._d2, self._d3
        with np.errstate(divide="ignore"):
            v = min(np.min(lim.velocity / d1), np.min(np.sqrt(0.5 * lim.acceleration / d2)), np.min(np.cbrt(lim.jerk / 3.0 / d3)))
            a = min(np.min(0.5 * lim.acceleration / d1), np.min(lim.jerk / 9.0 / (d2 * v)))
            j = float(np.min(lim.jerk / 3.0 / d1))
        return float(v), float(a), j

    def _timing(self, base: tuple[float, float, float], scale: float, entry_speed_fraction: float):
        """(profile, entry speed, top speed) with the u limits ``base * scale``, or None when
        the joints would exceed a limit. Entering too fast to stop by the end halves the entry."""
        v, a, j = (scale * x for x in base)
        speed0 = entry_speed_fraction * v
        for _ in range(8):
            profile = _profile_1d(speed0, v, a, j)
            if profile.position_extrema[0].max <= 1.0 + 1e-9:
                return (profile, speed0, v) if self._within_limits(profile) else None
            speed0 *= 0.5
        return None

    def _within_limits(self, profile: Trajectory, checks: int = 1000) -> bool:
        """Joint velocity, acceleration and jerk of the timed path, sampled, within the limits."""
        h = 1e-6
        t = np.linspace(0.0, profile.duration - h, checks)
        now = np.array([[x[0] for x in profile.at_time(ti)] for ti in t])
        ahead = np.array([profile.at_time(ti + h)[2][0] for ti in t])
        u, ud, udd = np.clip(now[:, 0], 0.0, 1.0), now[:, 1:2], now[:, 2:3]
        uddd = (ahead[:, None] - udd) / h
        d1, d2, d3 = self.path.spline(u, 1), self.path.spline(u, 2), self.path.spline(u, 3)
        lim, m = self.limits, self._margin
        return bool(
            np.all(np.abs(d1 * ud) <= m * lim.velocity)
            and np.all(np.abs(d2 * ud**2 + d1 * udd) <= m * lim.acceleration)
            and np.all(np.abs(d3 * ud**3 + 3.0 * d2 * ud * udd + d1 * uddd) <= m * lim.jerk)
        )

    def at(self, t: float) -> State:
        u, u_dot, u_ddot = self._profile.at_time(min(max(t, 0.0), self.duration))
        return self.path.state(float(np.clip(u[0], 0.0, 1.0)), u_dot[0], u_ddot[0])

    def entry_state(self) -> State:
        """The joint state the line starts in: what the segment before it must end in."""
        return self.path.state(0.0, self.start_speed, 0.0)


def _profile_1d(speed0: float, v: float, a: float, j: float) -> Trajectory:
    otg, inp, trajectory = Ruckig(1), InputParameter(1), Trajectory(1)
    inp.current_position, inp.current_velocity, inp.current_acceleration = [0.0], [speed0], [0.0]
    inp.target_position, inp.target_velocity, inp.target_acceleration = [1.0], [0.0], [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v], [a], [j]
    result = otg.calculate(inp, trajectory)
    if result not in (Result.Working, Result.Finished):
        raise TrajectoryError(f"Ruckig could not time the straight line ({result.name})")
    return trajectory


def _slerp(T_start: np.ndarray, T_goal: np.ndarray) -> Slerp:
    return Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([T_start[:3, :3], T_goal[:3, :3]])))
