"""A scripted push of one movable part, through contact alone: the proof that an object is
physically there for the arm (a part the fingers pass through never moves).

The hand, fingers closed and approaching along the push direction, goes to a point on the
part's surface, then straight on through where the surface was. The point is chosen on the
part's collision surface (privileged geometry) where its joint moves it fastest along the
push, and where nothing of the object stands in the hand's way for ``clearance`` behind it.
The push direction is the part's motion towards its farther limit. Joint targets come from the
control package's IK (:class:`actaim2.control.ik.IKSolver`, no collision checks, no planner):
a joint-space move to a pre-pose backed off along the push, then the straight line,
executed by :meth:`SimEnv.follow_trajectory`.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from actaim2.control.ik import IKOptions, IKSolver
from actaim2.control.model import RobotModel
from actaim2.sim.env import SimEnv
from actaim2.sim.objects.surface import surface_points
from actaim2.sim.success import moved_fraction


@dataclass(frozen=True)
class PushConfig:
    depth: float = 0.12  # m: how far past the surface point the fingertips go
    backoff: float = 0.12  # m: the pre-pose stands this far before the surface point
    clearance: float = 0.03  # m: radius of the hand's path kept free of the object's other points
    speed: float = 0.15  # m/s along the straight line
    max_reach: float = 0.8  # m: surface points farther from the robot base are not tried
    min_height: float = 0.08  # m: nor points this close to the floor
    candidates: int = 12  # surface points tried (the fastest-moving first) before giving up

    def __post_init__(self) -> None:
        if min(self.depth, self.backoff, self.clearance, self.speed, self.max_reach) <= 0 or self.candidates < 1:
            raise ValueError(f"PushConfig: lengths, speed and candidates must be positive, got {self}")


@dataclass(frozen=True)
class PushPlan:
    dof: int
    point: np.ndarray  # where the fingertips meet the part's surface (world)
    direction: np.ndarray  # unit push direction (world)
    sign: float  # +1: towards the upper limit, -1: towards the lower one
    path: list[np.ndarray]  # arm joint positions: the pre-pose, then the straight line, 1 cm apart

    @property
    def message(self) -> str:
        return f"pushed at {np.round(self.point, 3).tolist()} along {np.round(self.direction, 2).tolist()}"


@dataclass(frozen=True)
class PushResult:
    dof: int
    pushed: bool  # a surface point and an IK path were found and executed
    moved: float  # signed change of the DoF, as a fraction of its range (positive: the push's way)
    message: str


class ScriptedPush:
    """Pushes parts of the object loaded in ``env``; reusable across resets."""

    def __init__(self, env: SimEnv, config: PushConfig = PushConfig()):
        self.env = env
        self.config = config
        self.ik = IKSolver(RobotModel(env.spec), None, IKOptions(restarts=10))

    def push(self, dof: int, rng: np.random.Generator | None = None) -> PushResult:
        """Plan and execute a push of DoF ``dof``; the DoF's change says whether the part was there."""
        env = self.env
        lower, upper = env.object_limits()
        q0 = env.object_dof()
        plan = self.plan(dof, rng)
        if isinstance(plan, str):
            return PushResult(dof, False, 0.0, plan)
        self.execute(plan)
        moved = plan.sign * moved_fraction(q0, env.object_dof(), lower, upper)[dof]
        return PushResult(dof, True, float(moved), plan.message)

    def plan(self, dof: int, rng: np.random.Generator | None = None) -> PushPlan | str:
        """A push of DoF ``dof`` from where it is, the direction with more room first; or why
        there is none."""
        env, cfg = self.env, self.config
        rng = rng if rng is not None else np.random.default_rng(0)
        obj = env.object
        joint = obj.joints[dof]
        lower, upper = env.object_limits()
        q0 = env.object_dof()
        T_joint = joint.get_global_pose().to_transformation_matrix()
        axis, origin = T_joint[:3, 0], T_joint[:3, 3]
        part = surface_points([joint.child_link], spacing=0.01)
        others = surface_points([link for link in obj.links if link is not joint.child_link], spacing=0.01)
        if joint.type == "prismatic":
            velocity = np.broadcast_to(axis, part.shape)
        else:
            velocity = np.cross(axis, part - origin)
        speed = np.linalg.norm(velocity, axis=1)
        ok = (np.linalg.norm(part[:, :2], axis=1) < cfg.max_reach) & (part[:, 2] > cfg.min_height) & (speed > 1e-6)
        order = [int(k) for k in np.argsort(-speed, kind="stable") if ok[k]]
        room = {1.0: upper[dof] - q0[dof], -1.0: q0[dof] - lower[dof]}
        tried = 0
        for sign in sorted((s for s in room if room[s] > 0.1 * (upper[dof] - lower[dof])), key=lambda s: -room[s]):
            free = (k for k in order if self._path_is_free(part[k], sign * velocity[k] / speed[k], part, others))
            for k in itertools.islice(free, cfg.candidates):
                tried += 1
                p, d = part[k], sign * velocity[k] / speed[k]
                path = self._joint_path(p, d, rng)
                if path is not None:
                    return PushPlan(dof, p, d, sign, path)
        return (f"no reachable, unobstructed surface point on {joint.child_link.name} "
                f"({len(order)} candidates, {tried} tried for IK)")

    def execute(self, plan: PushPlan) -> None:
        """Close the fingers, move to the pre-pose in joint space, then follow the line."""
        env = self.env
        env.grip(closed=True)
        times, positions = self.timing(plan)
        env.follow_trajectory(times[:1], positions[:1])
        env.follow_trajectory(times[1:] - times[0], positions[1:], settle=0.3)

    def timing(self, plan: PushPlan) -> tuple[np.ndarray, np.ndarray]:
        """(times from now, positions) of the plan's waypoints from the arm's current joints: the
        free move at most 0.5 rad/s per joint (at least 1 s), the line at ``speed``."""
        path = np.asarray(plan.path)
        free_move = max(1.0, float(np.max(np.abs(path[0] - self.env.robot.arm_positions()))) / 0.5)
        return free_move + 0.01 / self.config.speed * np.arange(len(path)), path

    def _path_is_free(self, p: np.ndarray, d: np.ndarray, part: np.ndarray, others: np.ndarray) -> bool:
        """No object point within ``clearance`` of the hand's path before ``p`` (the part's own
        points in front of p too: the fingertips must meet the surface at p first)."""
        cfg = self.config
        for cloud in (part, others):
            rel = cloud - p
            along = rel @ d
            radial = np.linalg.norm(rel - along[:, None] * d, axis=1)
            if np.any((along < -0.01) & (along > -cfg.backoff) & (radial < cfg.clearance)):
                return False
        return True

    def _joint_path(self, p: np.ndarray, d: np.ndarray, rng: np.random.Generator) -> list[np.ndarray] | None:
        """Arm configurations: the pre-pose, then the straight line to ``depth`` past ``p``."""
        cfg, env = self.config, self.env
        R = _approach_frame(d)
        steps = np.arange(-cfg.backoff, cfg.depth + 1e-9, 0.01)
        seed = env.robot.arm_positions()
        path = []
        for s in steps:
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, p + s * d
            result = self.ik.solve(T, seed, rng=rng, use_cloud=False)
            if not result.success:
                return None
            if path and np.max(np.abs(result.angles - path[-1])) > 0.3:  # a jump: another IK branch
                return None
            path.append(result.angles)
            seed = result.angles
        return path


def _approach_frame(d: np.ndarray) -> np.ndarray:
    """A TCP rotation whose z (approach) is ``d`` and whose y (closing) is as horizontal as it can be."""
    z = d / np.linalg.norm(d)
    y = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(y) < 1e-3:
        y = np.cross(z, [1.0, 0.0, 0.0])
    y /= np.linalg.norm(y)
    return np.column_stack([np.cross(y, z), y, z])
