"""Real object folders in the simulator: preparation cold, load with the cache warm, hulls, physics rate.

``actaim2 bench sim --objects DIR [--cache CACHE]``:
  * prepare: ``prepare_objects`` of every folder together, in one pool of ``workers``
    processes, into CACHE (default: a new empty folder, so cold): wall seconds for all, CPU
    seconds per folder (CoACD), the issue's target being <= 5 min for the five shared objects
    on 2 cores;
  * load, warm cache: ``SimEnv.reset`` of each folder after another object was loaded (a real
    reload: URDF parsing, hull files read from the cache, PhysX cooking, settling);
  * hulls: convex collision shapes of the loaded object;
  * physics real-time factor with the object loaded and the arm following a trajectory;
  * a scripted push (:mod:`actaim2.rollout.push`): each DoF in turn, half-open (then open,
    then closed), pushed by the arm on joint targets until one moves by at least
    ``PUSH_MOVED`` of its range: proof that the object is physically there (a part the arm
    passes through never moves).
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

from actaim2.bench.physics import waving_arm

TARGET_PREPARE_S = 300.0
TARGET_PHYSICS_RTF = 10.0
PUSH_MOVED = 0.1  # fraction of a DoF's range a scripted push must move it by
PUSH_FROM = (0.5, 1.0, 0.0)  # the DoFs' starting fractions tried in turn
REFERENCE = ("storage_furniture", 0)  # a generated object: the physics rate to compare with


def run_objects_bench(folders: list[Path], workers: int = 2, seconds: float = 5.0,
                      cache_root: Path | None = None) -> tuple[list[dict], dict]:
    """(one row per folder, the all-folders row) as described in the module docstring."""
    with tempfile.TemporaryDirectory(prefix="actaim2-bench-hulls-") as tmp:
        return _run(folders, workers, seconds, Path(cache_root) if cache_root is not None else Path(tmp))


def _run(folders: list[Path], workers: int, seconds: float, cache_root: Path) -> tuple[list[dict], dict]:
    from actaim2.rollout.push import ScriptedPush
    from actaim2.sim.env import SimEnv
    from actaim2.sim.objects.hulls import HullCache
    from actaim2.sim.objects.prepare import prepare_objects

    cache = HullCache(cache_root)
    started = time.perf_counter()
    reports = prepare_objects(folders, cache, workers)
    total = {"objects": len(folders), "prepare_s": time.perf_counter() - started,
             "prepare_cpu_s": sum(r.cpu_s for r in reports), "hulls": sum(r.hulls for r in reports),
             "cold": not any(r.count("cached") for r in reports)}
    rows = []
    env = SimEnv("panda", hull_cache=cache.root)
    pusher = ScriptedPush(env)
    for k, (folder, report) in enumerate(zip(folders, reports)):
        if len(folders) > 1:
            env.reset(folder=folders[k - 1], seed=0)  # another object first: the next reset really loads
        else:
            env.sim.remove_object()
        started = time.perf_counter()
        info = env.reset(folder=folder, seed=0)
        rows.append({"object": folder.name, "load_s": time.perf_counter() - started, "category": info.category,
                     "scale": env.object.scale, "hulls": env.object.hulls, "dofs": len(info.dof_names),
                     "meshes": report.meshes, "decomposed": report.count("decomposed"), "prepare_cpu_s": report.cpu_s,
                     "physics_rtf": _arm_moving_rtf(env, seconds), "push": _push_any_part(env, pusher, folder)})
    env.reset(*REFERENCE, seed=0)  # the same workload beside a generated object, in the same run (same load)
    total["reference_rtf"] = _arm_moving_rtf(env, seconds)
    return rows, total


def _arm_moving_rtf(env, seconds: float) -> float:
    """Real-time factor of physics while the arm follows a trajectory from home."""
    env.robot.reset(env.spec.home, env.spec.gripper_open)
    controller = waving_arm(env, seconds)
    end, wall = env.time + seconds, time.perf_counter()
    while env.time < end:
        q, qd = controller.command(env.time + env.timestep)
        env.set_arm_targets(q, qd)
        env.step()
    return seconds / (time.perf_counter() - wall)


def _push_any_part(env, pusher, folder: Path) -> dict:
    """The first DoF a scripted push moves by PUSH_MOVED of its range, from half-open, then open,
    then closed (a lid that falls shut from half-open is pushed shut from open); else the push
    that moved a part most: {dof, moved (fraction of the range), tried (pushes)}."""
    best = {"dof": "", "moved": 0.0, "tried": 0}
    for fraction in PUSH_FROM:
        for k, name in enumerate(env.object.dof_names):
            env.reset(folder=folder, seed=0, dof_fraction=fraction)
            result = pusher.push(k)
            best["tried"] += 1
            if result.moved > best["moved"]:
                best.update(dof=name, moved=result.moved)
            if result.moved >= PUSH_MOVED:
                return best
    return best


def markdown(rows: list[dict], total: dict, workers: int) -> str:
    lines = ["| object | category | scale | DoFs | meshes (decomposed) | hulls | prepare: CPU s "
             "| load, warm cache (s) | physics, arm moving | scripted push moved |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['object']} | {r['category']} | {r['scale']:.3f} | {r['dofs']} | {r['meshes']} ({r['decomposed']}) "
                     f"| {r['hulls']} | {r['prepare_cpu_s']:.1f} | {r['load_s']:.2f} | {r['physics_rtf']:.1f}x "
                     f"| {_push_cell(r['push'])} |")
    verdict = "met" if total["prepare_s"] <= TARGET_PREPARE_S else "MISSED"
    worst = min(r["physics_rtf"] for r in rows) if rows else float("nan")
    state = "cold cache" if total["cold"] else "cache already filled: not a cold figure"
    lines.append(f"| all {total['objects']} ({workers} workers) | | | | | {total['hulls']} "
                 f"| {total['prepare_cpu_s']:.1f} CPU s, {total['prepare_s']:.1f} s wall ({state}): target <= "
                 f"{TARGET_PREPARE_S:.0f} s ({verdict}) "
                 f"| | slowest {worst:.1f}x: target >= {TARGET_PHYSICS_RTF:.0f}x "
                 f"({'met' if worst >= TARGET_PHYSICS_RTF else 'MISSED'}); generated {REFERENCE[0]} {REFERENCE[1]}: "
                 f"{total['reference_rtf']:.1f}x "
                 f"| {sum(r['push']['moved'] >= PUSH_MOVED for r in rows)} of {len(rows)} objects moved |")
    return "\n".join(lines)


def _push_cell(push: dict) -> str:
    moved = push["moved"] >= PUSH_MOVED
    where = f"{push['dof']} {push['moved']:.0%}" if push["dof"] else "nothing"
    return f"{'yes' if moved else 'NO'}: {where} ({push['tried']} pushes)"

