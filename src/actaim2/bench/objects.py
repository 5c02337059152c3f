"""Real object folders in the simulator: preparation cold, load with the cache warm, hulls, physics rate.

Per folder (``actaim2 bench sim --objects DIR``):
  * prepare, cold: ``prepare_objects`` on an empty hull cache (CoACD), wall and CPU seconds;
  * load, warm cache: ``SimEnv.reset`` of the folder after another object was loaded (a real
    reload: URDF parsing, hull files read from the cache, PhysX cooking, settling);
  * hulls: convex collision shapes of the loaded object;
  * physics real-time factor with the object loaded and the arm following a trajectory.
Then all folders together on an empty cache, in one pool of ``workers`` processes: the figure
the issue's target (<= 5 min on 2 cores for the five shared objects) is about.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

TARGET_PREPARE_S = 300.0
TARGET_PHYSICS_RTF = 10.0


def run_objects_bench(folders: list[Path], workers: int = 2, seconds: float = 5.0) -> tuple[list[dict], dict]:
    """(one row per folder, the all-folders row) as described in the module docstring."""
    from actaim2.bench.sim import _waving_arm
    from actaim2.sim.env import SimEnv
    from actaim2.sim.objects.hulls import HullCache
    from actaim2.sim.objects.prepare import prepare_objects

    rows = []
    with tempfile.TemporaryDirectory(prefix="actaim2-bench-hulls-") as tmp:
        for k, folder in enumerate(folders):  # each on its own empty cache: cold
            cache = HullCache(Path(tmp) / f"cold{k}")
            started = time.perf_counter()
            (report,) = prepare_objects([folder], cache, workers)
            rows.append({"object": folder.name, "prepare_s": time.perf_counter() - started, "prepare_cpu_s": report.cpu_s,
                         "meshes": report.meshes, "decomposed": report.count("decomposed"), "cache": cache.root})
        together = HullCache(Path(tmp) / "all")
        started = time.perf_counter()
        reports = prepare_objects(folders, together, workers)
        total = {"objects": len(folders), "prepare_s": time.perf_counter() - started,
                 "prepare_cpu_s": sum(r.cpu_s for r in reports), "hulls": sum(r.hulls for r in reports)}
        env = SimEnv("panda", hull_cache=together.root)
        for k, (folder, row) in enumerate(zip(folders, rows)):
            env.reset(folder=folders[k - 1] if len(folders) > 1 else folder, seed=0)  # another object first
            if len(folders) == 1:
                env.sim.remove_object()
            started = time.perf_counter()
            info = env.reset(folder=folder, seed=0)
            row.update(load_s=time.perf_counter() - started, category=info.category, scale=env.object.scale,
                       hulls=env.object.hulls, dofs=len(info.dof_names))
            env.robot.reset(env.spec.home, env.spec.gripper_open)
            controller = _waving_arm(env, seconds)
            end, wall = env.time + seconds, time.perf_counter()
            while env.time < end:
                q, qd = controller.command(env.time + env.timestep)
                env.set_arm_targets(q, qd)
                env.step()
            row["physics_rtf"] = seconds / (time.perf_counter() - wall)
            del row["cache"]
    return rows, total


def markdown(rows: list[dict], total: dict, workers: int) -> str:
    lines = ["| object | category | scale | DoFs | meshes (decomposed) | hulls | prepare, cold cache: wall s (CPU s) "
             "| load, warm cache (s) | physics, arm moving |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['object']} | {r['category']} | {r['scale']:.3f} | {r['dofs']} | {r['meshes']} ({r['decomposed']}) "
                     f"| {r['hulls']} | {r['prepare_s']:.1f} ({r['prepare_cpu_s']:.1f}) | {r['load_s']:.2f} "
                     f"| {r['physics_rtf']:.1f}x |")
    verdict = "met" if total["prepare_s"] <= TARGET_PREPARE_S else "MISSED"
    worst = min(r["physics_rtf"] for r in rows) if rows else float("nan")
    lines.append(f"| all {total['objects']} together ({workers} workers) | | | | | {total['hulls']} "
                 f"| {total['prepare_s']:.1f} ({total['prepare_cpu_s']:.1f}): target <= {TARGET_PREPARE_S:.0f} s ({verdict}) "
                 f"| | slowest {worst:.1f}x: target >= {TARGET_PHYSICS_RTF:.0f}x "
                 f"({'met' if worst >= TARGET_PHYSICS_RTF else 'MISSED'}) |")
    return "\n".join(lines)

