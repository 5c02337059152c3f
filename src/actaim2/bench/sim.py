"""`actaim2 bench sim`: physics rate, camera render time per path, real-time factor.

Measured on the default scene (Panda + storage_furniture instance 0, 240 Hz physics):
  * physics steps/s and real-time factor (actaim2.bench.physics): holding, executing a
    trajectory (the target's workload), and the expert manipulating a drawer; no cameras;
  * ms per camera frame for each render path (``sapien`` on Vulkan/lavapipe, ``raycast`` with
    Open3D): one 320x240 camera, the Azure Kinect's 320x288, a full ring5 observation with and
    without the robot, and the PointCloud2 encoding of the five clouds;
  * real-time factor of the whole loop - trajectory execution plus ring5 rendered at 5 Hz of
    sim time - running as fast as possible.
Targets: physics >= 10x real time while executing trajectories; a ring5 observation
<= 200 ms. Timings are medians; other jobs on the machine inflate them (load average printed).
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from actaim2.bench.physics import waving_arm

TARGET_PHYSICS_RTF = 10.0
TARGET_RING5_MS = 200.0
SCENE = dict(category="storage_furniture", instance=0, seed=0, dof_fraction=0.5)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per physics / loop measurement")
    parser.add_argument("--frames", type=int, default=10, help="renders per camera measurement")
    parser.add_argument("--paths", nargs="+", default=["sapien", "raycast"], help="render paths to measure")
    parser.add_argument("--camera-rate", type=float, default=5.0, help="ring5 observations per sim second in the loop")
    parser.add_argument("--objects", type=Path, help="instead: real object folders (a folder of them, or one): prepare cold, "
                                                     "load warm, hulls, physics rate with the arm moving (actaim2.bench.objects)")
    parser.add_argument("--workers", type=int, default=2, help="with --objects: decomposition processes")
    parser.add_argument("--cache", type=Path, help="with --objects: hull cache to prepare into (default: a new empty one: cold)")


def _run_loop(env, seconds: float, camera_rate: float) -> tuple[int, float]:
    """(physics steps, wall seconds) of the node's loop: sample, set targets, step, and render
    ring5 every 1/camera_rate sim seconds when ``camera_rate`` > 0."""
    controller = waving_arm(env, seconds)
    end, steps = env.time + seconds, 0
    next_frame = env.time
    started = time.perf_counter()
    while env.time < end:
        q, qd = controller.command(env.time + env.timestep)
        env.set_arm_targets(q, qd)
        env.step()
        steps += 1
        if camera_rate > 0 and env.time >= next_frame:
            env.observe()
            next_frame += 1.0 / camera_rate
    return steps, time.perf_counter() - started


def _median_ms(fn, frames: int) -> float:
    times = []
    for _ in range(frames):
        started = time.perf_counter()
        fn()
        times.append(time.perf_counter() - started)
    return 1000.0 * float(np.median(times))


def _bench_path(path: str, args) -> dict[str, float]:
    from actaim2.perception.cloud_codec import encode
    from actaim2.sim.cameras import make_rig
    from actaim2.sim.env import WORKSPACE_CENTER, SimEnv
    from actaim2.sim.observe import CameraRig

    env = SimEnv("panda", cameras="ring5", render_path=path)
    env.reset(**SCENE)
    env.observe()  # first picture: shader compilation, mesh simplification
    out = {
        "ring5": _median_ms(env.observe, args.frames),
        "ring5_hidden": _median_ms(lambda: env.observe(with_robot=False), args.frames),
    }
    frames = env.observe().frames
    out["encode"] = _median_ms(lambda: [encode(f.xyz, f.rgb) for f in frames.values()], args.frames)
    single_cameras = {"one_camera": make_rig("ring5", WORKSPACE_CENTER)[:1], "kinect": make_rig("azure_kinect", WORKSPACE_CENTER)}
    for key, cameras in single_cameras.items():
        rig = CameraRig(env.scene, cameras, env.render_path)
        rig.observe(env.time)
        out[key] = _median_ms(lambda: rig.observe(env.time), args.frames)
    steps, wall = _run_loop(env, args.seconds, args.camera_rate)
    out["loop_rtf"] = steps * env.timestep / wall
    return out


def main(args: argparse.Namespace) -> int:
    if args.objects is not None:
        return _main_objects(args)
    from actaim2.bench.physics import markdown, run_physics_bench
    from actaim2.sim.render_path import vulkan_device_error

    physics = run_physics_bench("panda", args.seconds)
    trajectory = next(row for row in physics if row["workload"] == "trajectory")
    physics_rate, physics_rtf = trajectory["steps_per_s"], trajectory["real_time_factor"]

    results: dict[str, dict[str, float] | str] = {}
    for path in args.paths:
        if path == "sapien" and vulkan_device_error() is not None:
            results[path] = f"n/a ({vulkan_device_error()})"
        else:
            results[path] = _bench_path(path, args)

    load = os.getloadavg()
    print(f"# actaim2 bench sim ({os.cpu_count()} CPUs, load average {load[0]:.1f} {load[1]:.1f} {load[2]:.1f}; "
          f"physics 240 Hz, medians of {args.frames} frames)\n")
    print(markdown(physics) + "\n")
    print("| measurement | result | target |")
    print("|---|---|---|")
    verdict = "met" if physics_rtf >= TARGET_PHYSICS_RTF else "MISSED"
    print(f"| physics, arm executing a trajectory | {physics_rate:,.0f} steps/s = {physics_rtf:.1f}x real time "
          f"| >= {TARGET_PHYSICS_RTF:.0f}x ({verdict}) |")
    rows = [
        ("one camera frame 320x240", "one_camera", "{:.1f} ms"),
        ("Azure Kinect frame 320x288", "kinect", "{:.1f} ms"),
        ("ring5 observation (5 x 320x240)", "ring5", "{:.1f} ms"),
        ("ring5 observation, robot hidden", "ring5_hidden", "{:.1f} ms"),
        ("ring5 -> 5 PointCloud2 payloads (encode)", "encode", "{:.1f} ms"),
        (f"real-time factor, trajectory + ring5 at {args.camera_rate:g} Hz", "loop_rtf", "{:.2f}x"),
    ]
    for label, key, fmt in rows:
        for path in args.paths:
            result = results[path]
            value = result if isinstance(result, str) else fmt.format(result[key])
            target = ""
            if key == "ring5" and not isinstance(result, str):
                target = f"<= {TARGET_RING5_MS:.0f} ms ({'met' if result[key] <= TARGET_RING5_MS else 'MISSED'})"
            print(f"| {label}, {path} | {value} | {target} |")
    return 0


def _main_objects(args: argparse.Namespace) -> int:
    from actaim2.bench.objects import markdown, run_objects_bench
    from actaim2.sim.objects.errors import ObjectLoadError
    from actaim2.sim.objects.prepare import find_object_folders

    try:
        folders = find_object_folders(args.objects)
    except ObjectLoadError as exc:
        print(f"actaim2 bench sim: {exc}")
        return 2
    rows, total = run_objects_bench(folders, args.workers, args.seconds, args.cache)
    load = os.getloadavg()
    print(f"# actaim2 bench sim --objects {args.objects} ({os.cpu_count()} CPUs, load average {load[0]:.1f} {load[1]:.1f} "
          f"{load[2]:.1f}; physics 240 Hz, {args.seconds:g} s of arm trajectory per object)\n")
    print(markdown(rows, total, args.workers))
    return 0
