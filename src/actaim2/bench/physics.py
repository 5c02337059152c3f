"""Physics throughput: steps per second and real-time factor while the robot moves.

Three workloads, each timed on wall-clock time around the physics loop only:
  * ``hold``        the arm holds still (PD targets fixed): the floor of the cost per step;
  * ``trajectory``  the arm follows a smooth joint trajectory, PD targets set every step
                    (what FollowJointTrajectory does), in free space;
  * ``manipulate``  the scripted expert pulls a drawer open and pushes it shut (contacts,
                    friction grasp); its IK planning is not timed.
``actaim2 bench sim`` reports these rows next to the camera timings.
"""
from __future__ import annotations

import time

import numpy as np


def run_physics_bench(robot: str = "panda", seconds: float = 5.0, timestep: float = 1.0 / 240.0) -> list[dict]:
    """One dict per workload: name, simulated seconds, wall seconds, steps/s, real-time factor."""
    from actaim2.rollout.expert import ExpertTask, ScriptedExpert
    from actaim2.sim.env import SimEnv

    env = SimEnv(robot, timestep=timestep)
    env.reset("storage_furniture", 2, seed=2)
    rows = []

    def timed(name: str, run) -> None:
        t0, wall0 = env.time, time.perf_counter()
        run()
        wall = time.perf_counter() - wall0
        sim = env.time - t0
        rows.append({"workload": name, "sim_s": sim, "wall_s": wall, "steps_per_s": sim / timestep / wall, "real_time_factor": sim / wall})

    timed("hold", lambda: env.step(int(seconds / timestep)))

    home = env.spec.home
    times = np.linspace(0.25, seconds, 40)
    phase = 2 * np.pi * times / seconds
    amplitude = 0.25 * np.sin(np.arange(len(home)) + 1.0)
    positions = home + np.outer(np.sin(phase), amplitude)
    velocities = np.outer(np.cos(phase) * 2 * np.pi / seconds, amplitude)
    env.robot.reset(home, env.spec.gripper_open)
    timed("trajectory", lambda: env.follow_trajectory(times, positions, velocities, settle=0.0))

    expert = ScriptedExpert(env)
    plans = []
    for direction in (+1, -1):
        env.reset("storage_furniture", 2, seed=2)
        plans.append(expert.plan(ExpertTask("drawer_0_joint", direction)))

    def manipulate() -> None:
        for plan in plans:
            env.reset("storage_furniture", 2, seed=2)
            expert.reach(plan)
            expert.manipulate(plan)
            expert.release(plan)

    timed("manipulate", manipulate)
    return rows


def markdown(rows: list[dict]) -> str:
    lines = ["| workload | simulated (s) | wall (s) | physics steps/s | real-time factor |", "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['workload']} | {r['sim_s']:.1f} | {r['wall_s']:.2f} | {r['steps_per_s']:.0f} | {r['real_time_factor']:.1f}x |")
    return "\n".join(lines)


def waving_arm(env, seconds: float):
    """An ArmController following a slow sinusoid around home for ``seconds``."""
    from actaim2.sim.joint_trajectory import ArmController, TrajectoryCommand

    joints = tuple(env.spec.arm_joints)
    times = np.arange(0.25, seconds + 0.25, 0.25)
    amplitude = np.array([0.4, 0.2, 0.3, 0.3, 0.4, 0.3, 0.5])[: len(joints)]
    positions = env.spec.home + np.sin(2 * np.pi * times[:, None] / 4.0) * amplitude
    controller = ArmController(joints, env.robot.arm_positions(), goal_tolerance=0.0, goal_time_tolerance=0.0)
    q, qd = env.robot.arm_positions(), np.zeros(len(joints))
    controller.start(TrajectoryCommand(joints, times, positions, None, None, None), env.time, q, qd)
    return controller
