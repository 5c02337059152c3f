"""How often the scripted teleoperator succeeds: its keyposes executed as control_node executes them.

    python -m actaim2.rollout.teleop_eval                                  # the issue-15 protocol, Kinova
    python -m actaim2.rollout.teleop_eval --robot panda --per-state 2

The protocol of the paper's real-robot fine-tuning data: the three-drawer shelf, three initial
states (the top, middle or bottom drawer half-open, the others shut), ``--per-state`` push and
as many pull demonstrations per state, each at a fresh random placement (seed) with the grasp
point randomised along the drawer edge. Each demonstration's keyposes go through the control
package's :class:`KeyposeRunner` (the planner, IK and options ``control_node`` uses by default,
velocity scaling 0.5) on the simulator stepped in-process, so this measures the same motions
``scripted_teleop`` sends to ``/execute_keypose``, without the node graph's wall-clock cost.
A demonstration succeeds when its drawer moved the asked way by more than 30 % of its range;
one the teleoperator cannot plan counts as a failure (the recorder would discard it).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

DEFAULT_VELOCITY_SCALING = 0.5  # control_node's default for goals without one
STATE_NAMES = ("bottom", "middle", "top")  # drawer_0 is the lowest (three_drawer_shelf recipe)
MODES = {"push": -1, "pull": +1}  # mode label -> direction of the half-open drawer: push shuts it, pull opens it
HALF_OPEN = 0.5


def initial_state(dofs: int, open_dof: int) -> list[float]:
    """DoF fractions of an initial state of the protocol: DoF ``open_dof`` half-open, the others shut."""
    fractions = [0.0] * dofs
    fractions[open_dof] = HALF_OPEN
    return fractions


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="kinova_j2s6s200", help="robot preset or YAML file")
    parser.add_argument("--category", default="three_drawer_shelf")
    parser.add_argument("--instance", type=int, default=0)
    parser.add_argument("--per-state", type=int, default=10, help="push and pull demonstrations per initial state")
    parser.add_argument("--seed", type=int, default=0, help="demonstration k uses placement seed seed + k")
    parser.add_argument("--grasp-spread", type=float, default=1.0, help="0: grasp the edge's centre; 1: anywhere along it")
    parser.add_argument("--verbose", action="store_true", help="print every demonstration")


def main(args: argparse.Namespace) -> int:
    from actaim2.control.collision import CollisionChecker, Workspace
    from actaim2.control.executor import KeyposeRunner
    from actaim2.control.ik import IKOptions, IKSolver
    from actaim2.control.model import RobotModel
    from actaim2.control.planner import KeyposePlanner, PlannerOptions
    from actaim2.rollout.expert import ExpertTask, PlanningError
    from actaim2.rollout.scripted_teleop import ScriptedTeleoperator, judged_success
    from actaim2.rollout.sim_executor import SimEnvExecutor
    from actaim2.sim.env import SimEnv

    env = SimEnv(args.robot)
    robot = RobotModel(env.spec)
    checker = CollisionChecker(robot, Workspace())
    planner = KeyposePlanner(robot, checker, IKSolver(robot, checker, IKOptions()), PlannerOptions())
    teleoperator = ScriptedTeleoperator(env, grasp_spread=args.grasp_spread, seed=args.seed)
    rows: dict[tuple[str, str], list[int]] = {}
    failures: dict[str, int] = {}
    started, k = time.perf_counter(), 0
    n_dofs = len(env.reset(args.category, args.instance, seed=args.seed).dof_names)
    for state in range(n_dofs):
        for label, direction in MODES.items():
            for _ in range(args.per_state):
                seed = args.seed + k
                k += 1
                rng = np.random.default_rng(seed)
                info = env.reset(args.category, args.instance, seed=seed, dof_fraction=initial_state(n_dofs, state))
                task = ExpertTask(info.dof_names[state], direction)
                runner = KeyposeRunner(planner, SimEnvExecutor(env), rng=np.random.default_rng(seed))
                try:
                    demo = teleoperator.demo(task, rng)
                except PlanningError as exc:
                    ok, moved, note = False, 0.0, f"not planned: {exc}"
                else:
                    note = ""
                    for keypose in demo.keyposes:
                        outcome = runner.run(keypose, DEFAULT_VELOCITY_SCALING)
                        if not outcome.success:
                            note = outcome.message  # the object decides success: a drawer at its stop stops the hand
                            break
                    ok, moved = judged_success(task, info.dof_names, info.dof_initial, env.object_dof(), info.dof_lower,
                                               info.dof_upper)
                counts = rows.setdefault((STATE_NAMES[state] if n_dofs == 3 else info.dof_names[state], label), [0, 0])
                counts[0] += ok
                counts[1] += 1
                if not ok:
                    cause = note.split(":")[0] if note else f"moved {moved:+.2f}"
                    failures[cause] = failures.get(cause, 0) + 1
                if args.verbose:
                    offset = f"{1000 * demo.grasp_offset:+.0f} mm" if note[:11] != "not planned" else "-"
                    print(f"seed {seed} {info.dof_names[state]} {label}: {'ok' if ok else 'FAILED'} moved {moved:+.2f}, "
                          f"grasp offset {offset}{': ' + note if note else ''}", file=sys.stderr, flush=True)
    wall = time.perf_counter() - started
    total_ok = sum(c[0] for c in rows.values())
    total = sum(c[1] for c in rows.values())
    print(f"Scripted teleoperator, robot {args.robot}, {args.category} instance {args.instance}, grasp spread "
          f"{args.grasp_spread}, seeds {args.seed}..{args.seed + k - 1}; load average {os.getloadavg()[0]:.1f}\n")
    print("| initial state (half-open drawer) | mode | success |\n|---|---|---|")
    for (state_name, label), (ok, n) in rows.items():
        print(f"| {state_name} | {label} | {ok}/{n} |")
    print(f"| all | all | **{total_ok}/{total} = {100 * total_ok / max(total, 1):.1f} %** |")
    if failures:
        print("\nfailures by cause: " + ", ".join(f"{cause} ({n})" for cause, n in sorted(failures.items())))
    print(f"\n{wall:.0f} s wall ({wall / max(total, 1):.1f} s per demonstration)")
    return 0


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    add_arguments(parser)
    raise SystemExit(main(parser.parse_args()))
