"""Scripted expert with privileged state: moves any movable part of an object either way.

It is the proof that every generated object can be manipulated by the simulated robot, and a
source of demonstrations. It reads what a policy never sees - the part's link pose, its
joint axis and the handle annotation - and follows the paper's four-phase primitive:

  INIT        pre-pose: the grasp pose backed off along the approach axis, gripper open
  REACH       straight line along the approach axis to p1
  GRASP       the gripper closes at p1 (on the handle; or, to push, just before it)
  MANIPULATE  p1 -> p2 along the part's motion: a straight line for a prismatic joint, an
              arc about the hinge for a revolute one (the hand turns with the part)

then opens the gripper and backs off. The manipulation should keep the arm (its fingers closed)
off the object's other parts, which stand still while the part and the hand move together,
and a pushing hand should touch the part only with its fingertips: a variant that does is
preferred, and one that brushes something is used only when no clean one exists (tight
stacks of half-open drawers leave no clean push). A manipulation the arm cannot
follow to its end may be cut short where the part has moved enough *and* stays when released:
a bistable toggle past its centre, a gravity-loaded part where its weight no longer pulls it
back harder than its joint friction holds it (privileged: the part's mass, centre of mass,
friction and behaviour). Opening means moving the DoF towards its upper limit,
closing towards its lower limit; a drawer (prismatic) is closed by pushing it with the closed
fingers, everything else is moved by grasping its handle. Every contact is physical: the
gripper holds the handle by friction only.

Inverse kinematics is the control package's (:class:`actaim2.control.ik.IKSolver`, with its
self-collision and ground checks); joint waypoints are timed for a Cartesian speed and the
joint velocity limits, then executed by :meth:`SimEnv.follow_trajectory`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from actaim2.control.collision import CollisionChecker, Workspace, points_away_from
from actaim2.control.ik import IKOptions, IKSolver
from actaim2.control.model import RobotModel
from actaim2.geometry import rotation_angle
from actaim2.sim.env import SimEnv
from actaim2.sim.objects.model import Handle
from actaim2.sim.objects.physics_table import BISTABLE, COUNTERBALANCED
from actaim2.sim.objects.surface import surface_points
from actaim2.sim.success import SUCCESS_FRACTION, moved_fraction

INIT, REACH, GRASP, MANIPULATE = 0, 1, 2, 3  # Keypose.phase values (DESIGN.md)
FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])  # the same grasp with the fingers swapped (turned about the approach axis)
HANDLE_CLEARANCE = 0.08  # m: obstacle points this close to the handle are ignored (the hand goes there)
MIN_PROGRESS = 0.36  # fraction of the range a cut-short manipulation must still cover (success: 0.3)
PUSH_CONTACT = 0.02  # m: the pushed part's points this close to the fingertips' contact point are theirs to touch
TILTED_OPENING = 0.6  # fraction of the full gripper stroke
FREE_MOVE_CLEARANCE = 0.1  # m: the joint-space move ends this much farther back than the pre-pose
# Grasp variants per handle kind, in order: the approach turned about the TCP x axis (the
# bar's axis: free for a round grip) and about its y axis (the closing direction: the pinch
# stays across the bar). A Panda cannot point its hand horizontally near shoulder height
# (joint 6 limit) nor straight down far away, so handles there are taken at an angle; flat
# grips (lips, toggles, sliders) turn less, or only about the closing axis.
_ROUND = [(a, 0) for a in (0, 25, 45, -25, -45)] + [(0, 25), (0, -25)]
TILTS = {"bar": _ROUND, "u_handle": _ROUND,
         "knob": _ROUND + [(0, 45), (0, -45)],  # a round cap: the pinch across it survives a steep tilt
         "lever": _ROUND + [(0, 40), (0, -40)],
         # a lip between a pocket and a free edge, a panel edge pinched across its thickness:
         # the fingers may turn along the lip or edge (about the closing axis), hardly across it
         "recessed": [(0, 0), (0, 20), (0, -20), (0, 35), (0, -35), (12, 0), (-12, 0)],
         "flush": [(0, 0), (0, 20), (0, -20), (0, 35), (0, -35), (12, 0), (-12, 0), (-30, 0), (-45, 0), (-60, 0),
                   (30, 0), (45, 0)],
         "spout": [(0, 0), (25, 0), (-25, 0), (0, 25), (0, -25), (0, 40), (0, -40)],
         "edge": [(0, 0), (20, 0), (30, 0), (-20, 0), (0, 25), (0, -25), (0, 45), (0, -45), (45, 0), (60, 0), (-30, 0),
                  (-45, 0), (-60, 0)],
         # small square knobs pinched on their flat faces: turning about the closing axis only
         "toggle": [(0, 0), (0, 20), (0, -20), (0, 35), (0, -35)],
         "slider": [(0, 0), (0, 20), (0, -20), (0, 35), (0, -35)]}


@dataclass(frozen=True)
class ExpertTask:
    """Move DoF ``joint`` towards its upper (``direction`` +1, open) or lower (-1, close) limit."""

    joint: str
    direction: int


@dataclass
class ExpertResult:
    task: ExpertTask
    success: bool  # the DoF moved the asked way by more than 30% of its range
    moved: float  # signed DoF change as a fraction of its range
    strategy: str  # "grasp" or "push"
    message: str
    keyposes: list[tuple[int, np.ndarray, bool]] = field(default_factory=list)  # (phase, T_world_tcp, gripper closed)


def expert_tasks(env: SimEnv) -> list[ExpertTask]:
    """Both directions of every movable part that has a handle annotation."""
    handled = {h.joint for h in env.object.handles}
    return [ExpertTask(name, d) for name in env.object.dof_names if name in handled for d in (+1, -1)]


class PlanningError(RuntimeError):
    pass


class ScriptedExpert:
    """Plans and executes :class:`ExpertTask` s in a :class:`SimEnv` (reset it first)."""

    def __init__(self, env: SimEnv, approach_distance: float = 0.1, push_standoff: float = 0.04, target_fraction: float = 0.9,
                 speed: float = 0.15, manipulation_speed: float = 0.08, seed: int = 0):
        self.env = env
        self.approach_distance = approach_distance
        self.push_standoff = push_standoff
        self.target_fraction = target_fraction
        self.speed = speed
        self.manipulation_speed = manipulation_speed
        model = RobotModel(env.spec)
        self._checker = CollisionChecker(model, Workspace(table_height=0.0))
        # the other parts, for manipulations: checked with the fingers closed, as they are then
        closed = RobotModel(dataclasses.replace(env.spec, gripper_open=env.spec.gripper_closed))
        self._sweep_checker = CollisionChecker(closed, Workspace(table_height=0.0))
        self._part_checker = CollisionChecker(closed, Workspace(table_height=0.0))  # the pushed part, off the fingertips
        self._ik_local = IKSolver(model, self._checker, IKOptions(restarts=0))
        self.seed = seed
        self._vmax = env.spec.max_velocity

    def run(self, task: ExpertTask) -> ExpertResult:
        """Plan, reach, manipulate, release and back off; the result is measured at the end."""
        obj = self.env.object
        q0 = obj.qpos()
        try:
            plan = self.plan(task)
        except PlanningError as exc:
            return ExpertResult(task, False, 0.0, "none", f"planning failed: {exc}")
        self.reach(plan)
        self.manipulate(plan)
        self.release(plan)
        moved = float(moved_fraction(q0, obj.qpos(), obj.lower, obj.upper)[plan.dof])
        success = moved * task.direction > SUCCESS_FRACTION
        return ExpertResult(task, success, moved, plan.strategy, "ok" if success else f"moved {moved:+.2f} of the range", plan.keyposes)

    def plan(self, task: ExpertTask) -> "ExpertPlan":
        """Choose the strategy and plan every motion from the current state (raises PlanningError)."""
        obj = self.env.object
        self._rng = np.random.default_rng(self.seed)
        i = obj.dof_index(task.joint)
        joint = obj.joints[i]
        handle = self._handle(task.joint)
        # a drawer is closed by pushing it: its closing motion runs along the approach axis
        approach_world = obj.link(handle.link).entity_pose.to_transformation_matrix()[:3, :3] @ np.asarray(handle.approach, float)
        opening_axis = joint.get_global_pose().to_transformation_matrix()[:3, 0]
        push = joint.type == "prismatic" and task.direction < 0 and float(-opening_axis @ approach_world) > 0.8
        q_now = float(obj.qpos()[i])
        span = obj.upper[i] - obj.lower[i]
        goal = obj.lower[i] + (self.target_fraction if task.direction > 0 else 1.0 - self.target_fraction) * span
        if push:
            goal = obj.lower[i] - 0.005  # the panel is pushed just past its stop
        approach, manipulation, retreat, keyposes, opening = self._plan(handle, joint, q_now, goal, push, self._stays(i, task.direction))
        return ExpertPlan(task, "push" if push else "grasp", handle, i, float(goal), opening, approach, manipulation, retreat, keyposes)

    def reach(self, plan: "ExpertPlan") -> None:
        """INIT, REACH and GRASP: open, move to the approach start, go straight in, close."""
        self.env.grip(closed=False, opening=plan.opening)
        self._move_free(plan.approach.joints[0])
        self.execute_motion(plan.approach, self.speed)
        self.env.grip(closed=True)

    def manipulate(self, plan: "ExpertPlan") -> None:
        """MANIPULATE: move the part, starting from where the grasp left it."""
        motion = plan.manipulation
        if plan.strategy == "grasp":  # closing the fingers may have nudged the part
            joint = self.env.object.joints[plan.dof]
            motion = self._regrasped(joint, plan.dof, plan.goal, motion)
        self.execute_motion(motion, self.manipulation_speed)

    def release(self, plan: "ExpertPlan") -> None:
        """Let go and back off along the approach axis (a pushing hand backs off closed, straight
        back the way it pushed: opening fingers could hook the handle)."""
        if plan.strategy == "grasp":
            self.env.grip(closed=False, opening=plan.opening)
        self.execute_motion(plan.retreat, self.speed)

    # -- planning -----------------------------------------------------------------------------
    def _handle(self, joint_name: str) -> Handle:
        for h in self.env.object.handles:
            if h.joint == joint_name:
                return h
        raise PlanningError(f"no handle annotation for {joint_name} in {self.env.object.folder}/handles.json")

    def _stays(self, i: int, direction: int):
        """A predicate on DoF values of part ``i``: released there, does it stay (or go on towards
        the goal) rather than fall back? (module docstring)"""
        obj = self.env.object
        joint = obj.joints[i]
        d = obj.dynamics.dynamics[i] if obj.dynamics is not None else None
        if d is None or d.behaviour == COUNTERBALANCED:
            return lambda q: True
        mid = 0.5 * (obj.lower[i] + obj.upper[i])
        if d.behaviour == BISTABLE:
            return lambda q: (q - mid) * direction > 0.05 * (obj.upper[i] - obj.lower[i])
        link = joint.child_link
        T_axis = joint.get_global_pose().to_transformation_matrix()
        axis, origin = T_axis[:3, 0], T_axis[:3, 3]
        com = (link.entity_pose * link.cmass_local_pose).p
        q_now = float(obj.qpos()[i])
        weight = np.array([0.0, 0.0, -9.81 * link.mass])

        def stays(q: float) -> bool:
            c = (_part_motion(joint.type, axis, origin, q - q_now) @ np.r_[com, 1.0])[:3]
            load = float(axis @ np.cross(c - origin, weight)) if joint.type != "prismatic" else float(axis @ weight)
            return load * direction >= -d.friction  # pulled back no harder than friction holds
        return stays

    def _plan(self, handle: Handle, joint, q_now: float, q_goal: float, push: bool, stays=lambda q: True):
        """Approach, manipulation and retreat motions (and the four keyposes) of the first variant
        that IK follows without jumps, whose free move misses the object and whose manipulation
        keeps the arm off the object's other parts (and a pushing hand off the pushed part but
        for its fingertips); it may be cut short only where ``stays``. Variants: the
        approach tilted about the handle's bar axis (where the handle allows it), the fingers
        either way round, for pushes the contact point beside or below the handle and the hand
        turned a quarter about its approach axis, and several
        arm configurations for the start (nearest the current one first)."""
        obj = self.env.object
        link_now = obj.link(handle.link).entity_pose.to_transformation_matrix()
        # the object as obstacle points, minus the handle region the hand is meant to touch
        handle_point = (link_now @ handle.tcp_in_link())[:3, 3]
        self._checker.set_cloud(points_away_from(surface_points(obj.links), handle_point, HANDLE_CLEARANCE))
        moving = _subtree(obj.link(handle.link))
        self._sweep_checker.set_cloud(surface_points([link for link in obj.links if link not in moving]))
        moving_points = surface_points(moving)
        T_axis = joint.get_global_pose().to_transformation_matrix()
        axis, origin = T_axis[:3, 0], T_axis[:3, 3]
        if push:
            # the fingertips press the panel beside (or below) the handle, never the handle itself:
            # pushing a handle, fingers slip over it and hook it on the way back
            side = handle.span / 2 + 0.025
            offsets = [(side, 0.0), (-side, 0.0), (0.0, 0.03), (0.0, -0.03)]
            spins = (0.0, np.pi / 2)  # closed fingers push the same either way round: turned, the hand is narrow vertically
            required = None
            travel = self.push_standoff + (q_now - q_goal)
            moves = [_part_motion("prismatic", axis, origin, -d) for d in np.linspace(0.0, travel, int(np.ceil(travel / 0.01)) + 1)]
        else:
            offsets, spins = [None], (0.0,)
            qs = _dof_path(joint.type, q_now, q_goal)
            moves = [_part_motion(joint.type, axis, origin, q - q_now) for q in qs]
            # where the arm cannot follow the whole way, going this far still moves the part enough
            enough = np.abs(qs - q_now) >= MIN_PROGRESS * float(joint.limit[0][1] - joint.limit[0][0])
            enough &= np.array([stays(float(q)) for q in qs])
            required = int(np.argmax(enough)) + 1 if enough.any() else None
        errors, brushing = [], None
        for rx, ry in np.deg2rad(TILTS.get(handle.kind, [(0, 0)])):
            for flip in (np.eye(4), FLIP):
                for offset, spin in ((o, a) for o in offsets for a in spins):
                    grasp = link_now @ handle.tcp_in_link() @ _rotate("x", rx) @ _rotate("y", ry) @ flip
                    if offset is not None:  # p1: standing off the contact point on the panel
                        grasp = grasp @ _translate(offset[0], offset[1], handle.depth - self.push_standoff) @ _rotate("z", spin)
                        touch = (grasp @ _translate(0, 0, self.push_standoff))[:3, 3]
                        self._part_checker.set_cloud(points_away_from(moving_points, touch, PUSH_CONTACT))
                    path = [move @ grasp for move in moves]
                    pre = grasp @ _translate(0, 0, -self.approach_distance)
                    # start the straight approach farther back when the arm can get there
                    for clearance in (FREE_MOVE_CLEARANCE, 0.0):
                        start = grasp @ _translate(0, 0, -self.approach_distance - clearance)
                        starts = self._configurations(start)
                        if starts:
                            break
                    for q_start in starts:
                        if self._free_move_collides(q_start):
                            errors.append("the free move to the approach start hits the object")
                            continue
                        try:
                            approach = self._follow(_line(start, grasp), q_start)
                            manipulation = self._follow(path, approach.joints[-1], required)
                            # back off along the approach axis; a pushing hand straight back the way it pushed
                            # (a tilted hand backing off along its own axis can hook the handle beside it)
                            end = manipulation.poses[-1]
                            back = [_part_motion("prismatic", axis, origin, d) @ end if push else end @ _translate(0, 0, -d)
                                    for d in np.linspace(0.0, self.approach_distance, 5)]
                            retreat = self._follow(back, manipulation.joints[-1])
                        except PlanningError as exc:
                            errors.append(str(exc))
                            continue
                        keyposes = [(INIT, pre, False), (REACH, grasp, False), (GRASP, grasp, True),
                                    (MANIPULATE, manipulation.poses[-1], True)]
                        # a steeply tilted hand opens less: its lower finger would hit the panel
                        opening = 1.0 if max(abs(rx), abs(ry)) < np.deg2rad(30) else TILTED_OPENING
                        found = (approach, manipulation, retreat, keyposes, opening)
                        if self._brushes(manipulation, offset is not None):
                            brushing = brushing or found
                            errors.append("the hand brushes another part, or the pushed part beyond its fingertips")
                            continue
                        return found
        if brushing is not None:
            return brushing
        raise PlanningError(f"{len(errors)} variants failed, e.g. {errors[0] if errors else 'no IK solution for any start pose'}")

    def _brushes(self, manipulation: "Motion", push: bool) -> bool:
        """Does the manipulation sweep the arm through another part, or (a push) touch the pushed
        part with more than its fingertips? At first touch the hand meets the pushed part as it
        will all the way, so that one configuration tells."""
        if any(self._sweep_checker.check(q) is not None for q in manipulation.joints[1:]):
            return True
        k = min(len(manipulation.joints) - 1, int(round(self.push_standoff / 0.01)))
        return push and self._part_checker.check(manipulation.joints[k]) is not None

    def _regrasped(self, joint, i: int, q_goal: float, planned: "Motion") -> "Motion":
        """The manipulation re-planned from the part's and hand's actual poses after the grasp
        (the planned one if IK cannot follow the new path)."""
        obj = self.env.object
        q_now = float(obj.qpos()[i])
        T_axis = joint.get_global_pose().to_transformation_matrix()
        tcp = self.env.tcp_pose()
        path = [_part_motion(joint.type, T_axis[:3, 0], T_axis[:3, 3], q - q_now) @ tcp for q in _dof_path(joint.type, q_now, q_goal)]
        target = planned.poses[-1]  # go no shorter than planned
        required = int(np.argmin([np.linalg.norm(T[:3, 3] - target[:3, 3]) for T in path])) + 1
        try:
            return self._follow(path, self.env.robot.arm_positions(), required)
        except PlanningError:
            return planned

    def _configurations(self, T: np.ndarray, seeds: int = 8, keep: int = 3) -> list[np.ndarray]:
        """Distinct IK solutions for ``T``: the one nearest the current arm first (the free move
        there sweeps the least), then others from random seeds, largest margin to the joint
        limits first (paths from there rarely run into a limit)."""
        model = self._ik_local.robot
        nearest, others = [], []
        for k in range(seeds):
            seed = self.env.robot.arm_positions() if k == 0 else model.random_angles(self._rng)
            result = self._ik_local.solve(T, seed, rng=self._rng, use_cloud=True)
            if result.success and all(np.abs(result.angles - q).max() > 0.2 for q in nearest + others):
                (nearest if k == 0 else others).append(result.angles)
        bounded = np.isfinite(model.lower) & np.isfinite(model.upper)
        lo, hi = model.lower[bounded], model.upper[bounded]
        others.sort(key=lambda q: float(np.min(np.minimum(q[bounded] - lo, hi - q[bounded]) / (hi - lo))), reverse=True)
        return (nearest + others)[:keep]

    def _solve(self, T: np.ndarray, seed: np.ndarray, solver: IKSolver) -> np.ndarray:
        result = solver.solve(T, seed, rng=self._rng, use_cloud=False)
        if not result.success:
            raise PlanningError(f"IK at {np.round(T[:3, 3], 3)}: {result.message}")
        return result.angles

    def _follow(self, poses: list[np.ndarray], seed: np.ndarray, required: int | None = None) -> "Motion":
        """IK along a dense Cartesian path, each pose seeded by the previous solution. With
        ``required``, a path that cannot be followed to its end is cut short after that many poses."""
        out, q = [], seed
        for k, T in enumerate(poses):
            try:
                q_next = self._solve(T, q, self._ik_local)
                if np.abs(q_next - q).max() > 0.35:
                    raise PlanningError(f"IK jumps {np.abs(q_next - q).max():.2f} rad along the path at {np.round(T[:3, 3], 3)}")
            except PlanningError:
                if required is not None and k >= required:
                    return Motion(np.asarray(out), poses[:k])
                raise
            out.append(q_next)
            q = q_next
        return Motion(np.asarray(out), poses)

    def _free_move_collides(self, q1: np.ndarray) -> bool:
        """Does the joint-space move from the current arm to ``q1`` touch the object (or ground)?"""
        q0 = self.env.robot.arm_positions()
        return any(self._checker.check(q0 + s * (q1 - q0), use_cloud=True) is not None for s in np.linspace(0.0, 1.0, 16)[1:])

    # -- execution ----------------------------------------------------------------------------
    def _move_free(self, q1: np.ndarray) -> None:
        """One joint-space move (minimum-jerk profile, a straight line in joint space) to ``q1``."""
        q0 = self.env.robot.arm_positions()
        duration = max(0.8, 1.5 * float(np.max(np.abs(q1 - q0) / self._vmax)))
        s = np.linspace(0.0, 1.0, 11)[1:]
        pos = q0 + np.outer(10 * s**3 - 15 * s**4 + 6 * s**5, q1 - q0)
        vel = np.outer((30 * s**2 - 60 * s**3 + 30 * s**4) / duration, q1 - q0)
        self.env.follow_trajectory(s * duration, pos, vel, settle=0.2)

    def execute_motion(self, motion: "Motion", speed: float) -> None:
        """Follow a motion's joint waypoints, timed for the Cartesian speed and joint limits."""
        joints, poses = motion.joints, motion.poses
        if len(joints) < 2:
            return
        cart = np.linalg.norm(np.diff([T[:3, 3] for T in poses], axis=0), axis=1)
        rot = np.array([rotation_angle(a[:3, :3], b[:3, :3]) for a, b in zip(poses[:-1], poses[1:])])
        dq = np.abs(np.diff(joints, axis=0)) / (0.5 * self._vmax)
        dt = np.maximum.reduce([cart / speed, rot * 0.12 / speed, dq.max(axis=1),
                                np.full(len(cart), 0.02)])
        times = np.cumsum(dt)
        vel = np.gradient(joints[1:], times, axis=0) if len(times) > 1 else np.zeros_like(joints[1:])
        vel[-1] = 0.0
        self.env.follow_trajectory(times, joints[1:], vel, settle=0.15)


@dataclass
class Motion:
    """Joint waypoints (first = where the motion starts) and the TCP poses they reach."""

    joints: np.ndarray
    poses: list[np.ndarray]

    def __getitem__(self, index: slice) -> "Motion":
        return Motion(self.joints[index], self.poses[index])


@dataclass
class ExpertPlan:
    """Everything :meth:`ScriptedExpert.run` executes for one task."""

    task: ExpertTask
    strategy: str  # "grasp" or "push"
    handle: Handle
    dof: int  # index of the DoF in the object's DoF order
    goal: float  # DoF value the manipulation aims at
    opening: float  # gripper opening (fraction of the stroke) while reaching and releasing
    approach: Motion  # from the approach start straight to p1
    manipulation: Motion  # p1 -> p2
    retreat: Motion
    keyposes: list[tuple[int, np.ndarray, bool]]


def _subtree(link) -> list:
    """A link and every link it carries."""
    out, stack = [], [link]
    while stack:
        current = stack.pop()
        out.append(current)
        stack.extend(current.children)
    return out


def _line(A: np.ndarray, B: np.ndarray, step: float = 0.01) -> list[np.ndarray]:
    """Poses from A to B along a straight line (orientation of A), about ``step`` apart."""
    n = max(2, int(np.ceil(np.linalg.norm(B[:3, 3] - A[:3, 3]) / step)) + 1)
    poses = []
    for s in np.linspace(0.0, 1.0, n):
        T = A.copy()
        T[:3, 3] = (1 - s) * A[:3, 3] + s * B[:3, 3]
        poses.append(T)
    return poses


def _translate(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _dof_path(joint_type: str, q_from: float, q_to: float) -> np.ndarray:
    """DoF values from ``q_from`` to ``q_to``, 1 cm or 3 degrees apart: the manipulation's waypoints."""
    step = 0.01 if joint_type == "prismatic" else np.deg2rad(3.0)
    return np.linspace(q_from, q_to, max(2, int(np.ceil(abs(q_to - q_from) / step)) + 1))


def _rotate(axis: str, angle: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler(axis, angle).as_matrix()
    return T


def _part_motion(joint_type: str, axis: np.ndarray, origin: np.ndarray, dq: float) -> np.ndarray:
    """World transform that moves a part by ``dq`` along (prismatic) or about (revolute) its joint axis."""
    T = np.eye(4)
    if joint_type == "prismatic":
        T[:3, 3] = axis * dq
        return T
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec(axis * dq).as_matrix()
    T[:3, :3] = R
    T[:3, 3] = origin - R @ origin
    return T
