"""`actaim2 bench control`: IK success and latency, Ruckig time, straight-line deviation.

Per robot preset:
  * IK: random *reachable* targets - the tcp pose of a random collision-free configuration
    inside the joint limits and the default workspace - solved from the home configuration
    (never from the configuration the target came from), with self- and environment
    collision checks. Success rate and wall time per solve (p50, p99).
  * Ruckig: one time-optimal, jerk-limited joint-space segment from home (at rest) to each
    IK solution, at full limits: wall time of the Python call (p50, p99).
  * Straight lines: from reachable poses, the tcp pulled back along its approach axis by
    10-20 cm, as MANIPULATE does; IK sampled along the line, timed by Ruckig, then the
    largest tcp distance from the line over the *sampled trajectory* sent to the controller
    (p50 and max over lines), and the planning time of a line.
Targets: IK success >= 99.5% with p50 <= 1 ms; Ruckig p50 <= 50 us; deviation
<= 2 mm. Other jobs on the machine inflate the timings: the load average is printed.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

TARGET_IK_SUCCESS = 0.995
TARGET_IK_P50_MS = 1.0
TARGET_RUCKIG_P50_US = 50.0
TARGET_DEVIATION_MM = 2.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robots", nargs="+", default=["panda", "kinova_j2s6s200"], help="robot presets")
    parser.add_argument("--targets", type=int, default=1000, help="random reachable IK targets per robot")
    parser.add_argument("--lines", type=int, default=50, help="straight lines per robot")
    parser.add_argument("--seed", type=int, default=0)


def _reachable_configurations(robot, checker, count: int, rng: np.random.Generator) -> list[np.ndarray]:
    out = []
    while len(out) < count:
        angles = robot.random_angles(rng)
        if checker.check(angles) is None:
            out.append(angles)
    return out


def _line_deviation(robot, trajectory, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    worst = 0.0
    for q in trajectory.positions:
        p = robot.fk(q)[:3, 3]
        s = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
        worst = max(worst, float(np.linalg.norm(p - (a + s * ab))))
    return worst


def bench_robot(name: str, targets: int, lines: int, seed: int) -> dict:
    from actaim2.control.collision import CollisionChecker
    from actaim2.control.ik import IKSolver
    from actaim2.control.line import LineError, LineSegment, solve_line
    from actaim2.control.model import RobotModel
    from actaim2.control.trajectory import JointPlanner, Limits, State, TrajectoryError, sample
    from actaim2.robots import load_robot_spec

    rng = np.random.default_rng(seed)
    robot = RobotModel(load_robot_spec(name))
    checker = CollisionChecker(robot)
    solver = IKSolver(robot, checker)
    home = robot.spec.home
    ik_times, solutions = [], []
    for angles in _reachable_configurations(robot, checker, targets, rng):
        result = solver.solve(robot.fk(angles), home, rng=rng)
        ik_times.append(result.seconds)
        if result.success:
            solutions.append(result.angles)

    limits = Limits.of(robot)
    planner = JointPlanner(robot.n)
    ruckig_times = []
    for goal in solutions:
        start = time.perf_counter()
        planner.plan(State.at_rest(home), State.at_rest(goal), limits)
        ruckig_times.append(time.perf_counter() - start)

    deviations, line_times, refused = [], [], 0
    for angles in _reachable_configurations(robot, checker, lines, rng):
        T_start = robot.fk(angles)
        T_goal = T_start.copy()
        T_goal[:3, 3] -= rng.uniform(0.10, 0.20) * T_start[:3, 2]
        start = time.perf_counter()
        try:
            path = solve_line(solver, T_start, T_goal, angles, anchor_at_end=False)
            trajectory = sample([LineSegment(path, limits)], robot.joint_names, 0.02)
        except (LineError, TrajectoryError):
            refused += 1  # the line leaves the workspace or crosses a limit: not a deviation sample
            continue
        line_times.append(time.perf_counter() - start)
        deviations.append(_line_deviation(robot, trajectory, T_start[:3, 3], T_goal[:3, 3]))
    return {
        "robot": name,
        "ik_success": len(solutions) / max(1, targets),
        "ik_ms": 1e3 * np.asarray(ik_times),
        "ruckig_us": 1e6 * np.asarray(ruckig_times),
        "deviation_mm": 1e3 * np.asarray(deviations),
        "line_ms": 1e3 * np.asarray(line_times),
        "lines_refused": refused,
        "targets": targets,
        "lines": lines,
    }


def _pct(values: np.ndarray, q: float) -> float:
    return float(np.percentile(values, q)) if len(values) else float("nan")


def main(args: argparse.Namespace) -> int:
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at start")
    print("\n| robot | IK targets | IK success | IK p50 ms | IK p99 ms | Ruckig p50 us | Ruckig p99 us "
          "| lines timed | line deviation p50 / max mm | line plan p50 ms | targets met |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    all_met = True
    for name in args.robots:
        r = bench_robot(name, args.targets, args.lines, args.seed)
        met = (r["ik_success"] >= TARGET_IK_SUCCESS and _pct(r["ik_ms"], 50) <= TARGET_IK_P50_MS
               and _pct(r["ruckig_us"], 50) <= TARGET_RUCKIG_P50_US
               and bool(len(r["deviation_mm"])) and float(np.max(r["deviation_mm"])) <= TARGET_DEVIATION_MM)
        all_met &= met
        dev = r["deviation_mm"]
        print(f"| {name} | {r['targets']} | {100 * r['ik_success']:.1f}% | {_pct(r['ik_ms'], 50):.2f} | {_pct(r['ik_ms'], 99):.2f} "
              f"| {_pct(r['ruckig_us'], 50):.1f} | {_pct(r['ruckig_us'], 99):.1f} "
              f"| {len(dev)}/{r['lines']} | {_pct(dev, 50):.3f} / {float(np.max(dev)) if len(dev) else float('nan'):.3f} "
              f"| {_pct(r['line_ms'], 50):.1f} | {'yes' if met else 'NO'} |", flush=True)
    print(f"\ntargets: IK success >= {100 * TARGET_IK_SUCCESS:.1f}% and p50 <= {TARGET_IK_P50_MS:g} ms, "
          f"Ruckig p50 <= {TARGET_RUCKIG_P50_US:g} us, straight-line deviation <= {TARGET_DEVIATION_MM:g} mm")
    print(f"load average at the end: {os.getloadavg()[0]:.2f} (other jobs on the machine inflate these numbers)")
    return 0 if all_met else 1
