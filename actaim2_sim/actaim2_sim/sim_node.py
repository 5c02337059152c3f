"""sim_node: the SAPIEN simulation as ROS 2 sees a real robot cell.

Publishes what the robot driver, the cameras and ros2_control publish on the real system
(DESIGN.md): /joint_states, organized PointCloud2 clouds per camera in its optical frame,
/tf_static (camera extrinsics, ``world -> <robot root>``), /clock (sim time), plus the
privileged /object_state. Serves FollowJointTrajectory and GripperCommand like ros2_control's
joint_trajectory_controller and gripper_action_controller, the JTC topic, and /reset_scene.

Where rclpy cannot do exactly what the C++ controllers do, the node stays as close as it can:
an invalid trajectory goal is accepted and at once aborted with its error_code and
error_string (a ROS 2 rejection carries no result); a goal replaced by a newer one is aborted
with a "preempted" error_string (rclpy cannot cancel a goal nobody asked to cancel).
GripperCommand positions are gap widths in metres, as the message says (parameter
``gripper_position_unit: finger_joint`` takes joint positions instead, as ros2_control's
gripper_action_controller does), and ``max_effort`` is the grip force limit in N (0 = the
robot's default, Panda 70 N); results report the position in the same unit and the force.

Threading: one timer steps physics, runs the controllers and renders the cameras when their
sim-time period is due, holding ``_lock`` (the simulation and the goal slots) while it works.
/reset_scene, the JTC topic and the action callbacks run on other executor threads and take the
same lock; action execute callbacks then wait for the loop to report an outcome. Hence the
MultiThreadedExecutor. Physics keeps priority: camera frames that fall due while the loop is
behind are skipped, never queued.

Shutdown (Ctrl-C, SIGTERM): rclpy's own signal handler would shut the context down at once, so
running goals could not be answered. Here the signal only sets a flag that the spin loop polls
(:func:`actaim2_ros.main.spin_until`); then the loop stops, every running goal is aborted, goals
that arrive later are aborted at once (an execute callback left waiting would keep its executor
thread, and with it the process, alive forever), and the executor spins a little longer so the
clients get their results.
"""
from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from actaim2_msgs.srv import ResetScene
from control_msgs.action import FollowJointTrajectory, GripperCommand
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, PointCloud2
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from actaim2.sim.env import SimEnv
from actaim2.sim.gripper_action import GripperGoal, GripperOutcome
from actaim2.sim.joint_trajectory import (
    INVALID_GOAL,
    ArmController,
    InvalidTrajectory,
    Outcome,
    command_from_points,
    validate,
)
from actaim2.sim.objects.catalog import category_instances, list_categories
from actaim2.sim.objects.loader import ObjectLoadError
from actaim2.sim.objects.prepare import find_object_folders, prepare_objects
from actaim2.sim.sensor_noise import SensorNoise
from actaim2_ros.main import SPIN_POLL, spin_until
from actaim2_ros.pointcloud2 import to_msg as cloud_to_msg
from actaim2_ros.stamps import duration_seconds, seconds_stamp, stamp_seconds
from actaim2_ros.transforms import StaticTransformPublisher, matrix_to_transform
from actaim2_sim.parameters import declare_parameters

MAX_CATCH_UP = 0.25  # wall seconds of lag made up per tick at most (no spiral of death when behind)
FAST_TICK_BUDGET = 0.02  # wall seconds of stepping per tick with real_time_factor 0
RELEASE_TIMEOUT = 1.0  # wall seconds at most for aborted goals' execute callbacks to return
RESULT_FLUSH = 0.2  # wall seconds of spinning that hand the last results to their clients


@dataclass
class PendingGoal:
    """A goal the loop executes. ``finish`` hands the outcome to the executor thread waiting in
    :meth:`conclude`, which moves the action goal to its final state and returns the result."""

    handle: ServerGoalHandle | None  # None for trajectories from the JTC topic
    done: threading.Event = field(default_factory=threading.Event)
    concluded: threading.Event = field(default_factory=threading.Event)
    result: object = None
    state: str = "abort"  # succeed | abort | canceled: the ServerGoalHandle method to call

    def finish(self, state: str, result: object) -> None:
        self.state, self.result = state, result
        self.done.set()

    def conclude(self) -> object:
        self.done.wait()
        getattr(self.handle, self.state)()
        self.concluded.set()
        return self.result


class SimNode(Node):
    def __init__(self) -> None:
        super().__init__("sim_node")
        self.p = declare_parameters(self)
        p = self.p
        self.env = SimEnv(
            p.robot,
            timestep=1.0 / p.physics_rate,
            cameras=p.rig,
            render_path=p.render_path,
            camera_size=(p.camera_width, p.camera_height),
            noise=SensorNoise.preset(p.sensor_noise, p.rig),
            hull_cache=Path(p.hull_cache).expanduser() if p.hull_cache else None,
        )
        if p.prepare_objects:
            self._prepare_objects(Path(p.prepare_objects).expanduser())
        self.get_logger().info(
            f"render path: {self.env.render_path} ({p.rig} rig, {len(self.env.rig.cameras)} camera(s)); "
            f"physics {p.physics_rate:.0f} Hz, real-time factor {p.real_time_factor or 'as fast as possible'}"
        )
        self.arm_joints = tuple(self.env.spec.arm_joints)
        self.n_arm = len(self.arm_joints)
        self.env.reset(p.category, p.instance, p.seed, p.dof_fraction)
        self._category = p.category  # an empty ResetScene category keeps this one
        if p.camera_rate > 0:  # the first picture compiles shaders: not inside the control loop
            started = time.monotonic()
            self.env.observe()
            self.get_logger().info(f"cameras warmed up in {time.monotonic() - started:.1f} s")
        self.arm = ArmController(self.arm_joints, self.env.robot.arm_positions(), p.goal_tolerance, p.goal_time_tolerance)
        self._arm_goal: PendingGoal | None = None
        self._gripper_goal: tuple[PendingGoal, GripperGoal] | None = None
        self._closing = False  # shutting down: the loop stops, every new goal is aborted at once
        self._loop_stopped = threading.Event()
        self._lock = threading.Lock()  # the simulation, the controllers, the goal slots, _closing

        loop_group, request_group, gripper_group = (MutuallyExclusiveCallbackGroup(), MutuallyExclusiveCallbackGroup(),
                                                   ReentrantCallbackGroup())
        self.joint_state_pub = self.create_publisher(JointState, "/joint_states", 10)
        self.object_state_pub = self.create_publisher(JointState, "/object_state", 10)
        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.cloud_pubs = {
            name: self.create_publisher(PointCloud2, cam.topic, qos_profile_sensor_data)
            for name, cam in self.env.rig.cameras.items()
        }
        self.tf_static = StaticTransformPublisher(self)
        self._publish_tf_static()

        arm_ns = f"/{p.arm_controller}"
        # Trajectory goals start in the order they arrive, as a JTC's: its own exclusive group takes
        # them one at a time, and each starts in handle_accepted_callback. Started from the execute
        # callback (a thread-pool task), a goal sent 0.3 s after another could start first and be
        # replaced by it (CI's teleop test saw its third jog lost that way).
        self._started: dict[bytes, PendingGoal] = {}  # by goal id, until its execute callback takes it
        self.trajectory_server = ActionServer(
            self, FollowJointTrajectory, f"{arm_ns}/follow_joint_trajectory", self._execute_trajectory,
            cancel_callback=lambda _: CancelResponse.ACCEPT, handle_accepted_callback=self._accept_trajectory,
            callback_group=MutuallyExclusiveCallbackGroup(),
        )
        self.gripper_server = ActionServer(
            self, GripperCommand, f"/{p.gripper_controller}/gripper_cmd", self._execute_gripper,
            cancel_callback=lambda _: CancelResponse.ACCEPT, callback_group=gripper_group,
        )
        self.create_subscription(JointTrajectory, f"{arm_ns}/joint_trajectory", self._on_trajectory_topic, 10,
                                 callback_group=request_group)
        self.create_service(ResetScene, "/reset_scene", self._on_reset_scene, callback_group=request_group)

        self._next_state_time = 0.0
        self._next_feedback_time = 0.0
        self._next_camera_time = 0.0
        self._wall_last = time.monotonic()
        self._sim_target = self.env.time
        self._loop_timer = self.create_timer(p.tick_period, self._tick, callback_group=loop_group)

    def _prepare_objects(self, path: Path) -> None:
        """Decompose the collision meshes of the real folders under ``path`` into the hull cache
        (before serving: never inside /reset_scene). A bad path stops the node (ValueError)."""
        started = time.monotonic()
        reports = prepare_objects(find_object_folders(path), self.env.hulls, os.cpu_count() or 1)
        counts = {k: sum(r.count(k) for r in reports) for k in ("decomposed", "convex", "cached")}
        self.get_logger().info(f"prepared {len(reports)} object(s) under {path} in {time.monotonic() - started:.1f} s: "
                               f"meshes {counts['decomposed']} decomposed, {counts['convex']} convex, {counts['cached']} "
                               f"already cached; {sum(r.hulls for r in reports)} hulls in {self.env.hulls.root}")

    # -- static frames ------------------------------------------------------------------------
    def _publish_tf_static(self) -> None:
        edges = [matrix_to_transform(np.eye(4), "world", self.env.spec.root_link)]
        seen = set()
        for cam in self.env.rig.cameras.values():
            for parent, child, T in cam.tf_chain:
                if child not in seen:
                    seen.add(child)
                    edges.append(matrix_to_transform(T, parent, child))
        self.tf_static.send(edges)

    # -- the loop -----------------------------------------------------------------------------
    def _tick(self) -> None:
        with self._lock:
            if self._closing:
                # Cancelled from its own callback: no other handler of this timer can be pending
                # (its group is busy), so none will try to take a cancelled timer.
                self._loop_timer.cancel()
                self._loop_stopped.set()
                return
            self._advance()

    def _advance(self) -> None:
        """Step physics to the target sim time of this tick; publish what fell due."""
        wall_now = time.monotonic()
        env = self.env
        if self.p.real_time_factor > 0:
            # an accumulated target keeps the fractions of a step that one tick leaves over
            rtf = self.p.real_time_factor
            self._sim_target = min(self._sim_target + (wall_now - self._wall_last) * rtf, env.time + MAX_CATCH_UP * rtf)
            while env.time + 0.5 * env.timestep < self._sim_target:
                self._physics_step()
        else:
            deadline = wall_now + FAST_TICK_BUDGET
            while time.monotonic() < deadline:
                for _ in range(10):
                    self._physics_step()
        self._wall_last = wall_now
        self.clock_pub.publish(Clock(clock=seconds_stamp(env.time)))
        if self.p.camera_rate > 0 and env.time >= self._next_camera_time:
            self._publish_clouds()
            self._next_camera_time = max(self._next_camera_time + 1.0 / self.p.camera_rate, env.time)

    def _physics_step(self) -> None:
        env = self.env
        q, qd = self.arm.command(env.time + env.timestep)
        env.set_arm_targets(q, qd)
        env.step()
        if env.time >= self._next_state_time:
            self._next_state_time = max(self._next_state_time + 1.0 / self.p.joint_state_rate, env.time)
            self._publish_states()
            self._monitor_goals()

    def _publish_states(self) -> None:
        stamp = seconds_stamp(self.env.time)
        names, q, qd = self.env.joint_state()
        msg = JointState(name=list(names), position=q.tolist(), velocity=qd.tolist())
        msg.header.stamp = stamp
        self.joint_state_pub.publish(msg)
        obj = self.env.object
        msg = JointState(name=obj.dof_names, position=obj.qpos().tolist(),
                         velocity=np.asarray(obj.articulation.get_qvel(), float).tolist())
        msg.header.stamp = stamp
        self.object_state_pub.publish(msg)

    def _publish_clouds(self) -> None:
        obs = self.env.observe(with_robot=not self.get_parameter("hide_robot").value)
        stamp = seconds_stamp(obs.sim_time)
        for name, frame in obs.frames.items():
            cam = obs.cameras[name]
            self.cloud_pubs[name].publish(cloud_to_msg(frame.xyz, frame.rgb, cam.frame_id, stamp))

    # -- arm: FollowJointTrajectory and the JTC topic --------------------------------------------
    def _monitor_goals(self) -> None:
        """Feedback, cancels and outcomes of the running goals (the loop holds ``_lock``)."""
        now = self.env.time
        _, q, qd = self.env.joint_state()
        self._monitor_arm(now, q[: self.n_arm], qd[: self.n_arm])
        self._monitor_gripper(now, self._gripper_position())

    def _monitor_arm(self, now: float, q: np.ndarray, qd: np.ndarray) -> None:
        goal = self._arm_goal
        if goal is not None and goal.handle is not None and goal.handle.is_cancel_requested:
            self.arm.hold(q)
            self._arm_goal = None
            goal.finish("canceled", FollowJointTrajectory.Result(error_code=0, error_string="canceled"))
            return
        if goal is not None and goal.handle is not None and now >= self._next_feedback_time:
            self._next_feedback_time = now + 1.0 / self.p.action_monitor_rate
            goal.handle.publish_feedback(self._trajectory_feedback(now, q, qd))
        outcome = self.arm.check(now, q)
        if outcome is None:
            return
        if outcome.error_code != 0:
            self.get_logger().warning(f"trajectory aborted: {outcome.message}")
        if goal is not None:
            self._arm_goal = None
            goal.finish("succeed" if outcome.error_code == 0 else "abort", _trajectory_result(outcome))

    def _monitor_gripper(self, now: float, position: float) -> None:
        if self._gripper_goal is None:
            return
        pending, tracker = self._gripper_goal
        if pending.handle.is_cancel_requested:
            self.env.set_gripper(self.env.robot.gripper_position())
            self._gripper_goal = None
            pending.finish("canceled", self._gripper_result(GripperOutcome(False, False, False)))
            return
        outcome = tracker.update(now, position)
        if outcome is not None:
            self._gripper_goal = None
            pending.finish("succeed" if outcome.succeeded else "abort", self._gripper_result(outcome))

    def _trajectory_feedback(self, now: float, q: np.ndarray, qd: np.ndarray) -> FollowJointTrajectory.Feedback:
        desired_q, desired_qd = self.arm.command(now)
        feedback = FollowJointTrajectory.Feedback(joint_names=list(self.arm_joints))
        feedback.header.stamp = seconds_stamp(now)
        feedback.desired = JointTrajectoryPoint(positions=desired_q.tolist(), velocities=desired_qd.tolist())
        feedback.actual = JointTrajectoryPoint(positions=q.tolist(), velocities=qd.tolist())
        feedback.error = JointTrajectoryPoint(positions=(desired_q - q).tolist(), velocities=(desired_qd - qd).tolist())
        return feedback

    def _start_trajectory(self, trajectory: JointTrajectory, goal: PendingGoal, tolerances: dict | None = None) -> None:
        """Validate and start (JTC: a valid trajectory replaces the running one). Raises
        InvalidTrajectory, leaving whatever runs untouched."""
        stamp = stamp_seconds(trajectory.header.stamp)
        command = command_from_points(
            list(trajectory.joint_names),
            [(duration_seconds(p.time_from_start), list(p.positions), list(p.velocities),
              list(p.accelerations)) for p in trajectory.points],
            start_time=stamp if stamp > 0 else None,
        )
        with self._lock:
            if self._closing:
                goal.finish("abort", FollowJointTrajectory.Result(error_code=INVALID_GOAL,
                                                                  error_string="aborted: sim_node shutting down"))
                return
            now = self.env.time
            validate(command, self.arm_joints, now)
            previous = self._arm_goal
            _, q, qd = self.env.joint_state()
            self.arm.start(command, now, q[: self.n_arm], qd[: self.n_arm], **(tolerances or {}))
            self._arm_goal = goal if self.arm.active is not None else None
            if self.arm.active is None:  # empty trajectory: hold position, done
                goal.finish("succeed", _trajectory_result(Outcome(0, "empty trajectory: holding position")))
        if previous is not None:
            previous.finish("abort", FollowJointTrajectory.Result(
                error_code=INVALID_GOAL, error_string="preempted: a new trajectory replaced this goal"))

    def _accept_trajectory(self, handle: ServerGoalHandle) -> None:
        """Start an accepted goal now (in arrival order), then let its execute callback wait for it."""
        goal = PendingGoal(handle)
        request = handle.request
        try:
            tolerances = {
                "path_tolerance": self.arm.tolerances_from([t.name for t in request.path_tolerance],
                                                           [t.position for t in request.path_tolerance],
                                                           np.zeros(self.n_arm)),
                "goal_tolerance": self.arm.tolerances_from([t.name for t in request.goal_tolerance],
                                                           [t.position for t in request.goal_tolerance],
                                                           self.arm.default_goal_tolerance),
            }
            goal_time = duration_seconds(request.goal_time_tolerance)
            if goal_time > 0:
                tolerances["goal_time_tolerance"] = goal_time
            self._start_trajectory(request.trajectory, goal, tolerances)
        except InvalidTrajectory as exc:
            self.get_logger().error(f"rejected trajectory goal: {exc}")
            goal.finish("abort", FollowJointTrajectory.Result(error_code=exc.error_code, error_string=str(exc)))
        self._started[bytes(handle.goal_id.uuid)] = goal
        handle.execute()

    def _execute_trajectory(self, handle: ServerGoalHandle) -> FollowJointTrajectory.Result:
        return self._started.pop(bytes(handle.goal_id.uuid)).conclude()

    def _on_trajectory_topic(self, msg: JointTrajectory) -> None:
        try:
            self._start_trajectory(msg, PendingGoal(None))
        except InvalidTrajectory as exc:
            self.get_logger().error(f"ignored trajectory on the topic: {exc}")

    # -- gripper: GripperCommand ------------------------------------------------------------------
    def _gripper_position(self) -> float:
        """The fingers' position in ``gripper_position_unit``."""
        robot = self.env.robot
        return robot.gripper_position() if self.p.gripper_position_unit == "finger_joint" else robot.gripper_gap()

    def _gripper_result(self, outcome: GripperOutcome) -> GripperCommand.Result:
        robot = self.env.robot
        joint = robot.gripper_joints[0]
        q, qd = float(robot.gripper_position()), float(self.env.joint_state()[2][self.n_arm])
        effort = float(np.clip(joint.stiffness * (robot.gripper_target() - q) - joint.damping * qd,
                               -joint.force_limit, joint.force_limit))
        return GripperCommand.Result(position=self._gripper_position(), effort=abs(robot.gripper.force_from_effort(effort)),
                                     stalled=outcome.stalled, reached_goal=outcome.reached_goal)

    def _execute_gripper(self, handle: ServerGoalHandle) -> GripperCommand.Result:
        command = handle.request.command
        pending = PendingGoal(handle)
        p = self.p
        with self._lock:
            problem = "" if np.isfinite(command.position) else f"position {command.position} is not finite"
            if not (np.isfinite(command.max_effort) and command.max_effort >= 0.0):
                problem = f"max_effort {command.max_effort} is not a force >= 0 N (0 = the default)"
            if self._closing or problem:
                if not self._closing:
                    self.get_logger().error(f"rejected gripper goal: {problem}")
                handle.abort()
                return self._gripper_result(GripperOutcome(False, False, False))
            if self._gripper_goal is not None:  # preempted, like the ros2_control controller
                self._gripper_goal[0].finish("abort", self._gripper_result(GripperOutcome(False, False, False)))
            tracker = GripperGoal(command.position, self.env.time, self._gripper_position(),
                                  p.gripper_goal_tolerance, p.gripper_stall_velocity, p.gripper_stall_timeout,
                                  p.gripper_allow_stalling)
            geometry = self.env.robot.gripper
            self.env.robot.set_gripper_force(float(command.max_effort))
            self.env.set_gripper(geometry.joint_from_gap(geometry.from_unit(command.position, p.gripper_position_unit)))
            self._gripper_goal = (pending, tracker)
        return pending.conclude()

    def _abort_goals(self, reason: str) -> list[PendingGoal]:
        """Abort the running arm and gripper goals (scene reset, shutdown); call with ``_lock``."""
        aborted = []
        if self._arm_goal is not None:
            result = FollowJointTrajectory.Result(error_code=INVALID_GOAL, error_string=f"aborted: {reason}")
            self._arm_goal.finish("abort", result)
            aborted.append(self._arm_goal)
        if self._gripper_goal is not None:
            self._gripper_goal[0].finish("abort", self._gripper_result(GripperOutcome(False, False, False)))
            aborted.append(self._gripper_goal[0])
        self._arm_goal, self._gripper_goal = None, None
        return aborted

    def finish(self) -> int:
        """Stop the loop, abort every running goal (and, from now on, every new one), and spin
        this node's executor until the loop has stopped, the aborted goals' execute callbacks have
        returned and their results have gone out to the clients: called by
        :func:`actaim2_ros.main.spin_until` before it shuts the executor down (a tick still in
        flight then would use the destroyed executor). Exit code 0."""
        executor = self.executor
        with self._lock:
            self._closing = True
            aborted = [goal for goal in self._abort_goals("sim_node shutting down") if goal.handle is not None]

        def released() -> bool:
            return self._loop_stopped.is_set() and all(goal.concluded.is_set() for goal in aborted)

        deadline = time.monotonic() + RELEASE_TIMEOUT
        while not released() and time.monotonic() < deadline and executor.context.ok():
            executor.spin_once(timeout_sec=SPIN_POLL)
        # the result responses are tasks of this executor, created as the execute callbacks return
        flushed = time.monotonic() + RESULT_FLUSH
        while time.monotonic() < flushed and executor.context.ok():
            executor.spin_once(timeout_sec=SPIN_POLL)
        return 0

    # -- scene --------------------------------------------------------------------------------
    def _on_reset_scene(self, request: ResetScene.Request, response: ResetScene.Response) -> ResetScene.Response:
        response.success = False
        fractions = list(request.dof_fractions) or request.dof_fraction
        if not np.all(np.isfinite(fractions) & (np.asarray(fractions) >= 0.0) & (np.asarray(fractions) <= 1.0)):
            response.message = f"dof_fraction(s) must be within [0, 1], got {fractions}"
            return response
        if request.object_path:
            # A user's PartNet-Mobility folder overrides category/instance (DESIGN.md).
            target = dict(folder=Path(request.object_path).expanduser())
            category = self._category
        else:
            category = request.category or self._category
            if category not in list_categories():
                response.message = f"unknown category '{category}'; valid categories: {', '.join(list_categories())}"
                return response
            instances = category_instances(category)
            # DESIGN.md: instance -1 draws one from the request's seed (reproducible random objects).
            instance = request.instance if request.instance >= 0 else int(np.random.default_rng(request.seed).choice(instances))
            if instance not in instances:
                response.message = (f"unknown instance {request.instance} of '{category}'; "
                                    f"valid instances: {instances[0]}..{instances[-1]} (or -1: drawn from the seed)")
                return response
            target = dict(category=category, instance=instance)
        with self._lock:
            try:
                info = self.env.reset(seed=request.seed, dof_fraction=fractions, **target)
            except (ObjectLoadError, ValueError) as error:
                response.message = f"cannot load {request.object_path or category}: {error}"
                self.get_logger().error(response.message)
                return response
            if not request.object_path:
                self._category = category
            self.arm.hold(self.env.robot.arm_positions())
            self._abort_goals("scene reset")
            # Every observation published from now on is rendered from the new scene.
            self._next_camera_time = self.env.time
            self._sim_target = self.env.time  # the reset's settling ran ahead of the clock: continue from there
            response.stamp = seconds_stamp(self.env.time)
        self.get_logger().info(f"scene reset: {info.object_id} (seed {info.seed}, dof_fraction "
                               f"{np.round(fractions, 2).tolist() if request.dof_fractions else round(request.dof_fraction, 2)})")
        response.success = True
        response.message = f"loaded {info.object_id}"
        response.object_id = info.object_id
        response.dof_names = list(info.dof_names)
        response.dof_lower = info.dof_lower.tolist()
        response.dof_upper = info.dof_upper.tolist()
        response.dof_initial = info.dof_initial.tolist()
        return response


def _trajectory_result(outcome: Outcome) -> FollowJointTrajectory.Result:
    return FollowJointTrajectory.Result(error_code=outcome.error_code, error_string=outcome.message)


def main(args: list[str] | None = None) -> int:
    # Action goals wait in executor threads for the loop to finish them: allow several at once.
    return spin_until(lambda _stop: SimNode(), "sim_node", args, threads=8)


if __name__ == "__main__":
    raise SystemExit(main())
