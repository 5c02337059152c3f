"""The simulator's Python API, without ROS: data collection, evaluation, the sim node and the
benchmark all drive the simulation through :class:`SimEnv`.

    env = SimEnv("panda", cameras="ring5")
    info = env.reset("storage_furniture", instance=3, seed=7)      # half-open by default
    env.follow_trajectory(times, positions, velocities)             # PD targets every physics step
    env.grip(closed=True)
    obs = env.observe(with_robot=False)                             # per-camera RGB-D + clouds
    env.success(info.dof_initial)                                   # some DoF moved > 30% of its range

Object state (``object_dof``, ``success``) is privileged: evaluation and labels only.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from actaim2.profiling import section, timed
from actaim2.robots import RobotSpec, load_robot_spec
from actaim2.sim.gripper_action import GripperGoal
from actaim2.sim.joint_trajectory import ActiveTrajectory, TrajectoryCommand
from actaim2.sim.objects.catalog import object_folder
from actaim2.sim.objects.hulls import HullCache
from actaim2.sim.objects.loader import LoadedObject, place
from actaim2.sim.objects.sizing import WORKSPACE_CENTER
from actaim2.sim.robot import DriveGains, SimRobot
from actaim2.sim.scene import SimScene
from actaim2.sim.success import SUCCESS_FRACTION, dof_success

if TYPE_CHECKING:
    from actaim2.sim.observe import Observation
    from actaim2.sim.randomisation import DomainRandomisation
    from actaim2.sim.sensor_noise import SensorNoise

# Object placement variation drawn from the reset seed: front distance, lateral offset, yaw.
PLACEMENT_JITTER = (0.03, 0.05, np.deg2rad(5.0))
# SimEnv.grip's ends: within GRIP_REACHED of the target, or fingers stopped (moving less than
# GRIP_STALL_SPEED on average over GRIP_STALL_WINDOW seconds: on a handle, or blocked).
GRIP_REACHED = 1e-4
GRIP_STALL_SPEED = 2e-3
GRIP_STALL_WINDOW = 0.05
# After a reset, physics runs until the object's DoFs move slower than SETTLE_SPEED (m/s or
# rad/s), for SETTLE_MIN_TIME to SETTLE_MAX_TIME simulated seconds (a lid falls shut in ~0.5 s).
SETTLE_SPEED = 2e-3
SETTLE_MIN_TIME = 0.1
SETTLE_MAX_TIME = 2.0


@dataclass(frozen=True)
class ResetInfo:
    """What a reset loaded (also the ResetScene service's response fields)."""

    object_id: str
    category: str
    instance: int
    seed: int
    folder: Path
    dof_names: list[str]
    dof_lower: np.ndarray
    dof_upper: np.ndarray
    dof_initial: np.ndarray


class SimEnv:
    """One robot and one articulated object in a SAPIEN scene, stepped by the caller."""

    def __init__(
        self,
        robot: str | RobotSpec = "panda",
        timestep: float = 1.0 / 240.0,
        cameras: str | None = None,
        render_path: str = "auto",
        camera_size: tuple[int, int] = (0, 0),
        cache_dir: Path | None = None,
        gains: DriveGains = DriveGains(),
        noise: "SensorNoise | None" = None,
        hull_cache: Path | None = None,
        randomisation: "DomainRandomisation | None" = None,
    ):
        """``cameras``: a rig name of :mod:`actaim2.sim.cameras` (``ring5``, ``azure_kinect``) or
        None for physics only. ``render_path``: ``auto``, ``sapien`` or ``raycast``
        (:mod:`actaim2.sim.render_path`); the scene gets a render system only for ``sapien``.
        ``noise``: a :class:`actaim2.sim.sensor_noise.SensorNoise` (default: the rig's own,
        ``SensorNoise.preset("rig", cameras)``: the documented sensor for azure_kinect, ideal ring5 cameras).
        ``hull_cache``: the folder of real objects' convex decompositions (:mod:`actaim2.sim.objects.hulls`;
        None: the default, ``~/.cache/actaim2/hulls``). ``randomisation``: domain randomisation
        (:mod:`actaim2.sim.randomisation`) drawn at every reset: its placement ranges replace
        ``PLACEMENT_JITTER``, its sensor model is the default ``noise``, and each reset's draw is
        :attr:`randomisation_draw`."""
        self.spec = load_robot_spec(robot) if isinstance(robot, str) else robot
        self.cache_dir = cache_dir
        self.hulls = HullCache(hull_cache)
        self.render_path = None
        if cameras is not None:
            from actaim2.sim.render_path import resolve_render_path

            self.render_path = resolve_render_path(render_path)
        self.sim = SimScene(self.spec, timestep, render=self.render_path == "sapien", gains=gains)
        self.rig = None
        if cameras is not None:
            from actaim2.sim.cameras import make_rig
            from actaim2.sim.observe import CameraRig
            from actaim2.sim.sensor_noise import SensorNoise

            specs = make_rig(cameras, WORKSPACE_CENTER, width=camera_size[0], height=camera_size[1])
            if noise is None:
                noise = randomisation.sensor_noise_model(cameras) if randomisation is not None else SensorNoise.preset("rig", cameras)
            self.rig = CameraRig(self.sim.scene, specs, self.render_path, noise)
        self.info: ResetInfo | None = None
        self.placement_jitter = PLACEMENT_JITTER if randomisation is None else randomisation.placement_jitter()
        self.randomiser = None
        if randomisation is not None:
            from actaim2.sim.randomisation import Randomiser

            self.randomiser = Randomiser(randomisation, self.sim, self.rig)
        self.randomisation_draw: dict | None = None  # the last reset's domain randomisation (lights, colours, noise)
        # Called with this env after every step() call (physics inside follow_trajectory, grip and
        # settle included): how a caller watches a motion it does not drive, e.g. an episode video.
        self.step_observers: list[Callable[["SimEnv"], None]] = []

    # -- scene access (cameras, node) -------------------------------------------------------
    @property
    def scene(self):
        """The ``sapien.Scene``."""
        return self.sim.scene

    @property
    def robot(self) -> SimRobot:
        return self.sim.robot

    @property
    def object(self) -> LoadedObject:
        if self.sim.object is None:
            raise RuntimeError("no object loaded: call reset() first")
        return self.sim.object

    @property
    def robot_links(self) -> list:
        return self.sim.robot.links

    @property
    def object_links(self) -> list:
        return [] if self.sim.object is None else self.sim.object.links

    @property
    def time(self) -> float:
        return self.sim.time

    @property
    def timestep(self) -> float:
        return self.sim.timestep

    # -- episode ------------------------------------------------------------------------------
    def reset(
        self,
        category: str | None = None,
        instance: int = 0,
        seed: int = 0,
        dof_fraction: float | Sequence[float] = 0.5,
        folder: Path | None = None,
        jitter: bool = True,
        scale: float | None = None,
    ) -> ResetInfo:
        """Load an object (a catalogue ``category``/``instance``, or a PartNet-Mobility style
        ``folder``), place it before the robot, set every DoF to ``dof_fraction`` of its range
        (0.5 = half-open), and send the robot home with the gripper open. Then physics runs until
        the object stands still (:meth:`settle`): a part that cannot rest at the requested
        fraction (a lid below its balance point, a toggle between its ends) ends at its nearest
        stable state, and ``dof_initial`` reports where it rests, the state success is measured from.

        ``seed`` draws the placement jitter (and the cameras' noise, and the domain randomisation);
        ``jitter=False`` places the object exactly where its recipe says. ``scale`` overrides a real folder's size rule
        (:mod:`actaim2.sim.objects.sizing`); its ``instance`` is reported as -1.
        """
        if folder is None:
            if category is None:
                raise ValueError("reset needs a category (and instance) or an object folder")
            folder = object_folder(category, instance, self.cache_dir)
        else:
            instance = -1  # a folder is no catalogue instance
        folder = Path(folder)
        rng = np.random.default_rng(seed)
        dx, dy, yaw = (rng.uniform(-j, j) for j in self.placement_jitter) if jitter else (0.0, 0.0, 0.0)
        with section("object load"):
            obj = self.sim.load_object(folder, scale=scale, hulls=self.hulls)
        place(obj, obj.front_distance + dx, dy, yaw)
        if np.ndim(dof_fraction) and len(dof_fraction) != len(obj.lower):
            raise ValueError(f"{len(dof_fraction)} dof fractions for the {len(obj.lower)} DoFs {obj.dof_names}")
        fraction = np.broadcast_to(np.asarray(dof_fraction, dtype=float), obj.lower.shape)
        if np.any((fraction < 0.0) | (fraction > 1.0)):
            raise ValueError(f"dof_fraction must be within [0, 1], got {dof_fraction}")
        initial = obj.lower + fraction * (obj.upper - obj.lower)
        obj.set_qpos(initial)
        self.robot.reset(self.spec.home, self.spec.gripper_open)
        self.settle()
        if self.randomiser is not None:  # before the rig's reset: its sensor model is part of the draw
            self.randomisation_draw = self.randomiser.apply(seed)
        if self.rig is not None:
            self.rig.reset(seed)
        self.info = ResetInfo(obj.object_id, obj.category, int(instance), int(seed), folder, obj.dof_names,
                              obj.lower.copy(), obj.upper.copy(), obj.qpos())
        return self.info

    @timed("physics")
    def step(self, n: int = 1) -> None:
        self.sim.step(n)
        for observer in self.step_observers:
            observer(self)

    def settle(self, min_time: float = SETTLE_MIN_TIME, max_time: float = SETTLE_MAX_TIME) -> float:
        """Step until every object DoF moves slower than ``SETTLE_SPEED`` (after at least
        ``min_time``, at most ``max_time`` simulated seconds); returns the time it took."""
        start = self.time
        chunk = max(1, int(round(0.025 / self.timestep)))
        while self.time - start < max_time - 1e-9:
            self.step(chunk)
            if self.time - start >= min_time - 1e-9 and np.max(np.abs(self.object.articulation.get_qvel()), initial=0.0) < SETTLE_SPEED:
                break
        return self.time - start

    # -- robot commands and state -----------------------------------------------------------
    def set_arm_targets(self, q: np.ndarray, qd: np.ndarray | None = None) -> None:
        self.robot.set_arm_target(np.asarray(q, dtype=float), None if qd is None else np.asarray(qd, dtype=float))

    def set_gripper(self, position: float) -> None:
        """Finger joint target (``spec.gripper_open`` .. ``spec.gripper_closed``; gap widths: ``robot.gripper``)."""
        self.robot.set_gripper_target(position)

    def grip(self, closed: bool, opening: float = 1.0, timeout: float = 1.5, force: float = 0.0) -> float:
        """Close (or open, to ``opening`` of the full stroke) the gripper with a grip force limit
        of ``force`` N (0 = the robot's default) and step until the fingers stop, on the handle
        or at their target; returns the finger position (a closed gripper stalled on a handle
        stops early). Stopped is judged as GripperCommand goals are
        (:mod:`actaim2.sim.gripper_action`), over a window of ``GRIP_STALL_WINDOW`` seconds."""
        spec = self.spec
        target = spec.gripper_closed if closed else spec.gripper_closed + opening * (spec.gripper_open - spec.gripper_closed)
        self.robot.set_gripper_force(force)
        self.set_gripper(target)
        goal = GripperGoal(target, self.time, self.robot.gripper_position(), GRIP_REACHED, GRIP_STALL_SPEED,
                           GRIP_STALL_WINDOW, allow_stalling=True)
        for _ in range(int(timeout / self.timestep)):
            self.step()
            if goal.update(self.time, self.robot.gripper_position()) is not None:
                break
        return self.robot.gripper_position()

    def joint_state(self) -> tuple[list[str], np.ndarray, np.ndarray]:
        """(names, positions, velocities) of the arm and gripper joints (/joint_states)."""
        return self.robot.joint_names, self.robot.joint_positions(), self.robot.joint_velocities()

    def tcp_pose(self) -> np.ndarray:
        """4x4 pose of the canonical ``tcp`` in ``world``."""
        return self.robot.tcp_pose()

    def follow_trajectory(self, times: np.ndarray, positions: np.ndarray, velocities: np.ndarray | None = None,
                          settle: float = 0.1) -> None:
        """Execute an arm trajectory given as time-stamped waypoints (time from now, arm joint
        positions, optional velocities), interpolated like ros2_control's joint_trajectory_controller
        (:mod:`actaim2.sim.joint_trajectory`), setting the PD targets every physics step; then
        hold the last point for ``settle`` seconds."""
        names = tuple(self.spec.arm_joints)
        command = TrajectoryCommand(names, np.asarray(times, float), np.asarray(positions, float),
                                    None if velocities is None else np.asarray(velocities, float), None, None)
        robot = self.robot
        now = self.time
        arm = robot.arm_index
        trajectory = ActiveTrajectory(command, names, now, robot.arm_positions(), robot.articulation.get_qvel()[arm].astype(float))
        end = trajectory.end_time + settle
        while self.time < end - 1e-9:
            q, qd = trajectory.sample(self.time + self.timestep)
            robot.set_arm_target(q, qd)
            self.step()

    # -- object state (privileged) ----------------------------------------------------------
    def object_dof(self) -> np.ndarray:
        return self.object.qpos()

    def object_limits(self) -> tuple[np.ndarray, np.ndarray]:
        return self.object.lower.copy(), self.object.upper.copy()

    def success(self, initial: np.ndarray | None = None, fraction: float = SUCCESS_FRACTION) -> bool:
        """Some DoF moved by more than ``fraction`` of its range since ``initial`` (default: the reset)."""
        if initial is None:
            if self.info is None:
                raise RuntimeError("no episode: call reset() first")
            initial = self.info.dof_initial
        return dof_success(initial, self.object_dof(), self.object.lower, self.object.upper, fraction)

    # -- observation --------------------------------------------------------------------------
    def observe(self, with_robot: bool = True) -> "Observation":
        """Every camera's RGB-D frame (:class:`actaim2.sim.observe.Observation`); with
        ``with_robot=False`` the robot is neither drawn nor occludes (the paper's O_init / O_final)."""
        if self.rig is None:
            raise RuntimeError("this SimEnv has no cameras: construct it with cameras='ring5' (or another rig)")
        hidden = set() if with_robot else self.sim.robot_entity_ids()
        return self.rig.observe(self.time, hidden)
