"""Inverse kinematics of the `tcp`: damped least squares on the SE(3) error, with restarts.

Each iteration takes a damped Gauss-Newton step on the 6-D error ``log6(T_tcp^-1 T_goal)``
(Jacobian ``Jlog6 . J_tcp``), integrates it on the configuration manifold (continuous
joints stay (cos, sin)) and projects onto the joint limits. The first attempt starts from
the current joints, so the answer is the nearby solution and trajectories stay short;
further attempts start from random configurations. A converged solution is accepted only
when it is collision-free (:class:`CollisionChecker`).

When nothing is accepted the failure says why, by the first that applies:
  * ``self_collision`` / ``environment_collision``: solutions exist, but all collide;
  * ``joint_limits``: the pose is reached when joint limits are ignored;
  * ``unreachable``: even without joint limits the closest pose stays far (beyond
    ``unreachable_distance`` / ``unreachable_angle``) or is out of the arm's reach sphere;
  * ``no_convergence``: the solver got close but not within tolerance.
"""
from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass
from enum import Enum

import numpy as np
import pinocchio as pin

from actaim2.control.collision import CollisionChecker
from actaim2.control.model import RobotModel
from actaim2.profiling import timed


class IKFailure(str, Enum):
    UNREACHABLE = "unreachable"
    JOINT_LIMITS = "joint_limits"
    SELF_COLLISION = "self_collision"
    ENVIRONMENT_COLLISION = "environment_collision"
    NO_CONVERGENCE = "no_convergence"


@dataclass(frozen=True)
class IKOptions:
    position_tolerance: float = 1e-4  # m
    orientation_tolerance: float = 1e-3  # rad
    max_iterations: int = 60  # per attempt
    restarts: int = 40  # random restarts after the seeded attempt
    damping: float = 1e-6  # lambda^2 = damping + error_damping * |e|^2 in (J J^T + lambda^2 I):
    error_damping: float = 1e-2  # heavy far from the goal (robust), vanishing near it (fast)
    max_step: float = 0.4  # rad per iteration and joint (keeps steps in the linear regime)
    limit_margin: float = 1e-4  # rad kept from each joint limit
    unreachable_distance: float = 0.01  # m: closest unconstrained pose farther than this = unreachable
    unreachable_angle: float = 0.05  # rad


@dataclass(frozen=True)
class IKResult:
    success: bool
    angles: np.ndarray | None  # joint angles (continuous joints unwrapped near the seed)
    failure: IKFailure | None
    message: str
    attempts: int
    seconds: float


class IKSolver:
    """IK for one robot model and collision scene; reusable, not thread-safe (shared data)."""

    def __init__(self, robot: RobotModel, checker: CollisionChecker | None, options: IKOptions = IKOptions()):
        self.robot = robot
        self.checker = checker
        self.options = options
        model = robot.model
        bounded = ~robot.continuous
        self._bounded_idx_q = np.array([model.joints[int(j) + 1].idx_q for j in np.flatnonzero(bounded)], dtype=int)
        self._bounded_idx_v = np.array([model.joints[int(j) + 1].idx_v for j in np.flatnonzero(bounded)], dtype=int)
        self._lo = robot.lower[bounded] + options.limit_margin
        self._hi = robot.upper[bounded] - options.limit_margin
        self._shoulder, self._reach = _reach_sphere(robot)

    @timed("IK")
    def solve(
        self,
        T_world_tcp: np.ndarray,
        seed: np.ndarray,
        rng: np.random.Generator | None = None,
        use_cloud: bool = True,
    ) -> IKResult:
        """Joint angles putting `tcp` at ``T_world_tcp`` (4x4), starting from ``seed`` angles."""
        start = time.perf_counter()
        opts = self.options
        rng = rng if rng is not None else np.random.default_rng()
        goal = pin.SE3(np.asarray(T_world_tcp, dtype=float))
        seed = np.asarray(seed, dtype=float)
        if np.linalg.norm(goal.translation - self._shoulder) > self._reach:
            return self._fail(
                IKFailure.UNREACHABLE,
                f"target is {np.linalg.norm(goal.translation - self._shoulder):.3f} m from the shoulder, "
                f"beyond the arm's reach of {self._reach:.3f} m",
                0,
                start,
            )
        collisions: Counter[str] = Counter()
        last_collision = ""
        for attempt in range(opts.restarts + 1):
            q0 = self.robot.to_q(seed if attempt == 0 else self.robot.random_angles(rng))
            q, converged, _ = self._descend(q0, goal, clamp=True)
            if not converged:
                continue
            angles = self.robot.to_angles(q, near=seed)
            hit = self.checker.check(angles, use_cloud=use_cloud) if self.checker is not None else None
            if hit is None:
                return IKResult(True, angles, None, "ok", attempt + 1, time.perf_counter() - start)
            collisions[hit.kind] += 1
            last_collision = str(hit)
        attempts = opts.restarts + 1
        if collisions:
            kind = IKFailure.ENVIRONMENT_COLLISION if collisions["environment"] >= collisions["self"] else IKFailure.SELF_COLLISION
            return self._fail(kind, f"every solution collides (e.g. {last_collision})", attempts, start)
        return self._classify_without_limits(goal, seed, rng, attempts, start)

    def _classify_without_limits(self, goal: pin.SE3, seed: np.ndarray, rng: np.random.Generator, attempts: int, start: float) -> IKResult:
        """Why no attempt converged: solve again ignoring joint limits and look at the residual."""
        best_pos, best_rot = np.inf, np.inf
        for attempt in range(min(self.options.restarts, 10) + 1):
            q0 = self.robot.to_q(seed if attempt == 0 else self.robot.random_angles(rng))
            _, converged, (pos, rot) = self._descend(q0, goal, clamp=False)
            if converged:
                return self._fail(IKFailure.JOINT_LIMITS, "the pose is only reached outside the joint limits", attempts, start)
            if pos + 0.1 * rot < best_pos + 0.1 * best_rot:
                best_pos, best_rot = pos, rot
        residual = f"closest pose {best_pos * 1000:.1f} mm / {np.degrees(best_rot):.1f} deg away"
        if best_pos > self.options.unreachable_distance or best_rot > self.options.unreachable_angle:
            return self._fail(IKFailure.UNREACHABLE, f"pose out of the arm's workspace ({residual})", attempts, start)
        return self._fail(IKFailure.NO_CONVERGENCE, f"no convergence within tolerance ({residual})", attempts, start)

    def _descend(self, q: np.ndarray, goal: pin.SE3, clamp: bool) -> tuple[np.ndarray, bool, tuple[float, float]]:
        """Damped Gauss-Newton from q; (q, converged, (position error, orientation error))."""
        model, data, fid, opts = self.robot.model, self.robot.data, self.robot.tcp_frame, self.options
        eye = np.eye(6)
        pos_err = rot_err = np.inf
        for _ in range(opts.max_iterations):
            pin.computeJointJacobians(model, data, q)
            oMf = pin.updateFramePlacement(model, data, fid)
            fMg = oMf.actInv(goal)
            err = pin.log6(fMg).vector
            pos_err = float(np.linalg.norm(goal.translation - oMf.translation))
            rot_err = float(np.linalg.norm(err[3:]))
            if pos_err < opts.position_tolerance and rot_err < opts.orientation_tolerance:
                return q, True, (pos_err, rot_err)
            J = pin.Jlog6(fMg.inverse()) @ pin.getFrameJacobian(model, data, fid, pin.LOCAL)
            damping = eye * (opts.damping + opts.error_damping * float(err @ err))
            v = J.T @ np.linalg.solve(J @ J.T + damping, err)
            if clamp:
                # Joints resting on a limit and pushed outwards drop out of this step
                # (active set): the others then do the whole job instead of a clipped part.
                qb, vb = q[self._bounded_idx_q], v[self._bounded_idx_v]
                blocked = ((qb <= self._lo + 1e-9) & (vb < 0)) | ((qb >= self._hi - 1e-9) & (vb > 0))
                if blocked.any():
                    J[:, self._bounded_idx_v[blocked]] = 0.0
                    v = J.T @ np.linalg.solve(J @ J.T + damping, err)
            peak = np.max(np.abs(v))
            if peak > opts.max_step:
                v *= opts.max_step / peak
            q = pin.integrate(model, q, v)
            if clamp:
                q[self._bounded_idx_q] = np.clip(q[self._bounded_idx_q], self._lo, self._hi)
        return q, False, (pos_err, rot_err)

    def _fail(self, failure: IKFailure, message: str, attempts: int, start: float) -> IKResult:
        return IKResult(False, None, failure, f"{failure.value}: {message}", attempts, time.perf_counter() - start)


def _reach_sphere(robot: RobotModel) -> tuple[np.ndarray, float]:
    """Centre (first joint's origin at the home pose) and radius (sum of link lengths + tcp
    offset) of a sphere containing every tcp position: targets outside it are unreachable."""
    model, data = robot.model, robot.model.createData()
    pin.forwardKinematics(model, data, robot.to_q(robot.spec.home))
    reach = sum(np.linalg.norm(model.jointPlacements[j].translation) for j in range(2, model.njoints))
    reach += np.linalg.norm(model.frames[robot.tcp_frame].placement.translation)
    return data.oMi[1].translation.copy(), float(reach)
