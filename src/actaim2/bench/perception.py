"""`actaim2 bench perception`: clouds in -> orthographic views out, p50/p99, in-process and through the node.

Scenes are ray cast (``actaim2.perception.synthetic``) with the simulator's camera rigs
(``actaim2.sim.cameras``): ring5 = five 320x240 RGB clouds around the object, azure_kinect = one
320x288 xyz-only cloud (the driver's depth-only layout, point_step 16). The scene holds a
floor, a cabinet-sized box and the Panda at home, whose points the self-filter removes from the
views, as in deployment.

* in-process: PointCloud2 payload bytes -> decode -> fuse -> self-filter -> views with the rig's
  perception configuration (``actaim2/perception/configs/<rig>.yaml``, resolution overridden),
  timed with ``time.perf_counter`` around decoding plus :meth:`Perception.process`. Two older
  paths run interleaved with it, so all figures come from the same machine under the same load,
  both read from git history (``actaim2.bench.baseline``), not kept in the tree: the whole path
  as it was at ``--baseline`` (before its speed-ups; its outputs were identical), and today's
  path with the renderer as it was before splatting (one pixel per point, hard z-buffer;
  ``ortho_views.py`` at :data:`SPLAT_BASELINE`, whose views had other units, which does not
  change their cost). Like fusion_node, the process keeps freed memory in its heap
  (``actaim2.perception.memory``) for every path.
* through the node: ``fusion_node`` and ``latency_probe`` run as separate processes (``ros2 run``,
  a private ROS_DOMAIN_ID, loopback only); latency is the probe's publish of a cloud set to its
  receipt of the /ortho_views message carrying that set's stamp. Each configuration runs at the
  target rate (10 Hz ring5, 15 Hz Azure) and at 30 Hz input, whose output rate is the node's
  capacity; then the same with ``fusion_node`` of ``--baseline`` (its sources exported from git).

Prints markdown tables. Other jobs on the machine inflate the numbers: say so when quoting them.
"""

from __future__ import annotations

import argparse
import array
import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from actaim2.bench.baseline import (
    BASELINE_REVISION,
    export_tree,
    modules_at,
    node_command,
    python_path,
)
from actaim2.bench.processes import private_ros_env, ros_run_command, start_logged, stop_group

SPLAT_BASELINE = "6bab265"  # the last ortho_views.py with one pixel per point (before splatting)
# The modules of the perception path, each after the ones it imports (a revision's, in-process).
PATH_MODULES = [
    "actaim2.perception.cloud_codec",
    "actaim2.perception.fusion",
    "actaim2.perception.self_filter",
    "actaim2.perception.ortho_views",
    "actaim2.perception.pipeline",
]
SPLAT_COST_LIMIT = (
    "ring5",
    128,
    1.2,
)  # ring5 -> 128 px p50 within 1.2x of the renderer before splatting
# In-process p50 (ms) for 128 px views; node output rate (Hz) at its input rate (NODE_RATES).
TARGETS = {
    ("ring5", "in-process", 128): ("p50 <= 12 ms", lambda p50, hz: p50 <= 12.0),
    ("ring5", "node"): ("15 Hz", lambda p50, hz: hz >= 15.0 * 0.95),
    ("azure_kinect", "node"): ("30 Hz", lambda p50, hz: hz >= 30.0 * 0.95),
}
NODE_RATES = {"ring5": 15.0, "azure_kinect": 30.0}  # the cameras' rates the node must keep up with
CAPACITY_RATE = 30.0
TARGET = np.array([0.7, 0.0, 0.25])  # the object the cameras look at (world)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--rigs", nargs="+", default=["ring5", "azure_kinect"], choices=["ring5", "azure_kinect"]
    )
    parser.add_argument("--resolutions", nargs="+", type=int, default=[128, 224])
    parser.add_argument(
        "--repeats", type=int, default=40, help="in-process repetitions per configuration"
    )
    parser.add_argument(
        "--duration", type=float, default=8.0, help="s of node measurement per rate"
    )
    parser.add_argument(
        "--threads", type=int, default=1, help="torch CPU threads (the node's default is 1)"
    )
    parser.add_argument("--skip-node", action="store_true", help="in-process numbers only")
    parser.add_argument(
        "--fastdds-profile",
        type=Path,
        help="Fast DDS XML profile for both processes (FASTRTPS_DEFAULT_PROFILES_FILE)",
    )
    parser.add_argument(
        "--baseline",
        default=BASELINE_REVISION,
        help="git revision whose perception path (in-process and fusion_node) is timed beside "
        "today's ('' = skip)",
    )
    parser.add_argument(
        "--splat-baseline",
        default=SPLAT_BASELINE,
        help="git revision whose ortho_views.render_views is timed in today's path ('' = skip)",
    )


@dataclass(frozen=True)
class SceneCamera:
    topic: str
    frame_id: str
    xyz: np.ndarray  # (H, W, 3) optical frame
    rgb: np.ndarray | None
    tf_chain: tuple[tuple[str, str, np.ndarray], ...]
    T_world_optical: np.ndarray


@dataclass(frozen=True)
class Scene:
    rig: str
    cameras: list[SceneCamera]
    joints: dict[str, float]


def build_scene(rig: str) -> Scene:
    from actaim2.perception.synthetic import RaycastScene, box_mesh, robot_collision_meshes
    from actaim2.robots import load_robot_spec
    from actaim2.sim.cameras import make_rig

    spec = load_robot_spec("panda")
    joints = dict(zip(spec.arm_joints, map(float, spec.home)))
    joints.update({name: spec.gripper_open for name in spec.gripper_joints})
    meshes = [
        (box_mesh([0.6, 0.0, -0.01], [2.0, 2.0, 0.02]), (150, 120, 90)),  # floor / table top
        (box_mesh(TARGET + [0.1, 0.0, 0.0], [0.3, 0.5, 0.5]), (180, 40, 40)),  # cabinet
        (box_mesh(TARGET + [-0.07, 0.1, 0.1], [0.04, 0.12, 0.02]), (60, 60, 200)),  # handle
    ] + [(m, (230, 230, 230)) for m in robot_collision_meshes(spec, joints)]
    scene = RaycastScene(meshes)
    cameras = []
    for cam in make_rig(rig, TARGET):
        xyz, rgb = scene.capture(
            cam.T_world_optical,
            cam.width,
            cam.height,
            np.rad2deg(2 * np.arctan(cam.width / (2 * cam.fx))),
        )
        cameras.append(
            SceneCamera(
                cam.topic,
                cam.frame_id,
                xyz,
                None if rig == "azure_kinect" else rgb,
                cam.tf_chain,
                cam.T_world_optical,
            )
        )
    return Scene(rig, cameras, joints)


def save_scene(scene: Scene, path: Path) -> None:
    """The npz that ``latency_probe`` replays."""
    arrays: dict[str, np.ndarray] = {
        "n_cameras": np.array(len(scene.cameras)),
        "joint_names": np.array(list(scene.joints)),
        "joint_positions": np.array(list(scene.joints.values())),
    }
    for i, cam in enumerate(scene.cameras):
        arrays[f"xyz{i}"] = cam.xyz
        if cam.rgb is not None:
            arrays[f"rgb{i}"] = cam.rgb
        arrays[f"topic{i}"] = np.array(cam.topic)
        arrays[f"frame{i}"] = np.array(cam.frame_id)
        arrays[f"chain_parents{i}"] = np.array([a for a, _, _ in cam.tf_chain])
        arrays[f"chain_children{i}"] = np.array([b for _, b, _ in cam.tf_chain])
        arrays[f"chain_T{i}"] = np.stack([T for _, _, T in cam.tf_chain])
    np.savez(path, **arrays)


def in_process(
    scene: Scene, config, repeats: int, baseline: str = "", splat_baseline: str = ""
) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], dict[str, float]]:
    """Wall and CPU milliseconds per set: payload bytes -> views, robot removed from the views.

    Returns {"today": (wall, cpu)} and, given revisions, {"<baseline>": ..., "renderer of
    <splat_baseline>": ...}, timed in the same loop (alternating), so that load on a shared machine
    hits all alike; a revision git cannot show is reported and left out. CPU time of this process
    is reported next to wall time because other jobs on a shared machine stretch wall time; with
    one torch thread, CPU time approximates an idle machine. Second: where today's wall time
    goes, ms per set for each section the path marks (``actaim2.profiling``) and "rest".
    """
    from actaim2.perception import cloud_codec, fusion, pipeline, self_filter
    from actaim2.profiling import Profile, recording
    from actaim2.robots import load_robot_spec

    def path_of(codec, fusion_module, pipeline_module, filter_module, render=None):
        """A payloads -> views function through these modules (``render``: another renderer)."""
        robot_filter = filter_module.RobotSelfFilter(
            load_robot_spec("panda"), config.self_filter_margin
        )
        robot_filter.set_joint_positions(list(scene.joints), list(scene.joints.values()))
        perception = pipeline_module.Perception(config, robot_filter)

        def run(payloads) -> None:
            clouds = []
            for wire, T in payloads:
                decoded = codec.decode(
                    wire.fields, wire.data, wire.height, wire.width, wire.point_step, wire.row_step
                )
                clouds.append(fusion_module.CameraCloud(decoded.xyz, decoded.rgb, T))
            if render is None:
                perception.process(clouds)
            else:
                shown = perception.without_robot(perception.fuse(clouds))
                render(shown.xyz, shown.rgb, config.center, config.half_extent, config.resolution)

        return run

    paths = {"today": path_of(cloud_codec, fusion, pipeline, self_filter)}
    if baseline:
        try:
            old = modules_at(baseline, PATH_MODULES)
            paths[baseline] = path_of(
                *(
                    old[f"actaim2.perception.{m}"]
                    for m in ("cloud_codec", "fusion", "pipeline", "self_filter")
                )
            )
        except ValueError as exc:
            print(f"perception path of {baseline} not timed: {exc}")
    if splat_baseline:
        try:
            module = "actaim2.perception.ortho_views"
            renderer = modules_at(splat_baseline, [module])[module].render_views
            paths[f"renderer of {splat_baseline}"] = path_of(
                cloud_codec, fusion, pipeline, self_filter, renderer
            )
        except ValueError as exc:
            print(f"renderer before splatting not timed: {exc}")
    # Payloads as a ROS subscription delivers a PointCloud2's data: a (writable) array.array of bytes.
    payloads = [
        (replace(wire, data=array.array("B", wire.data)), c.T_world_optical)
        for wire, c in ((cloud_codec.encode(c.xyz, c.rgb), c) for c in scene.cameras)
    ]
    times: dict[str, tuple[list, list]] = {name: ([], []) for name in paths}
    profile = Profile()
    for i in range(repeats + 3):  # the first runs pay for allocations and lazy imports
        for name, run in list(paths.items())[
            :: 1 if i % 2 else -1
        ]:  # each goes first in turn (caches)
            with recording(profile if name == "today" and i >= 3 else Profile()):
                start, start_cpu = time.perf_counter(), time.process_time()
                run(payloads)
                wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu
            if i >= 3:
                times[name][0].append(wall * 1e3)
                times[name][1].append(cpu * 1e3)
    stages = {name: seconds * 1e3 / repeats for name, seconds in profile.seconds.items()}
    stages["rest"] = float(np.mean(times["today"][0])) - sum(stages.values())
    return {name: (np.array(wall), np.array(cpu)) for name, (wall, cpu) in times.items()}, stages


def _ros_run(
    executable: str, params: dict, env: dict[str, str], log: Path, **popen
) -> subprocess.Popen:
    return start_logged(
        ros_run_command("actaim2_perception", executable, params), env, log, **popen
    )


def through_node(
    scene: Scene,
    config,
    rates: list[float],
    duration: float,
    workdir: Path,
    fastdds_profile: Path | None,
    tree: Path | None = None,
) -> list[dict]:
    """One fusion_node with ``config`` (today's, or the one of an exported ``tree``); one probe
    run per input rate. Returns the probes' JSON results."""
    from actaim2.perception.config import save_perception_config

    env = private_ros_env(fastdds_profile)
    node_env = env if tree is None else dict(env, PYTHONPATH=python_path(tree))
    scene_file = workdir / f"{scene.rig}.npz"
    save_scene(scene, scene_file)
    config_file = workdir / f"perception_{scene.rig}_{config.resolution}.yaml"
    save_perception_config(config, config_file)
    command = ros_run_command(
        "actaim2_perception",
        "fusion_node",
        {"cloud_topics": [c.topic for c in scene.cameras], "perception_config": str(config_file)},
    )
    if tree is not None:
        command = node_command(tree, "actaim2_perception", "fusion_node", command[4:])
    log = (
        workdir
        / f"fusion_node_{scene.rig}_{config.resolution}{'' if tree is None else '_baseline'}.log"
    )
    node = start_logged(command, node_env, log, stdout=subprocess.DEVNULL)
    results = []
    try:
        for rate in rates:
            probe = _ros_run(
                "latency_probe",
                {"scene_file": str(scene_file), "rate": rate, "duration": duration},
                env,
                workdir / f"probe_{scene.rig}_{config.resolution}_{rate:g}.log",
                stdout=subprocess.PIPE,
                text=True,
            )
            out, _ = probe.communicate(timeout=duration + 120)
            lines = [line for line in out.splitlines() if line.startswith("{")]
            result = (
                json.loads(lines[-1])
                if lines
                else {"error": f"probe exited {probe.returncode} without a result"}
            )
            results.append(dict(result, rate=rate))
    finally:
        stop_group(node, timeout=10.0)
    return results


def _row(
    rig: str,
    resolution: int,
    path: str,
    latencies: np.ndarray,
    rate_in: str,
    rate_out: float | None,
    cpu: np.ndarray | None = None,
) -> str:
    p50, p99 = (
        np.percentile(latencies, [50, 99]) if len(latencies) else (float("nan"), float("nan"))
    )
    key = (rig, path, resolution) if path == "in-process" else (rig, path)
    target, check = TARGETS.get(key, ("", None))
    verdict = ""
    if check is not None and (path == "in-process" or rate_in == f"{NODE_RATES[rig]:g}"):
        verdict = f"{target}: {'met' if check(p50, rate_out or 0.0) else 'MISSED'}"
    out_text = f"{rate_out:.1f}" if rate_out is not None else ""
    cpu_text = f"{np.percentile(cpu, 50):.1f}" if cpu is not None else ""
    return f"| {rig} | {resolution} | {path} | {rate_in} | {out_text} | {p50:.1f} | {p99:.1f} | {cpu_text} | {len(latencies)} | {verdict} |"


def main(args: argparse.Namespace) -> int:
    import torch

    from actaim2.perception.config import load_perception_config
    from actaim2.perception.memory import keep_freed_memory

    torch.set_num_threads(args.threads)
    kept = keep_freed_memory()  # as fusion_node does: freed buffers stay in the heap
    print(
        f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at start, torch threads {args.threads}, "
        f"freed memory kept in the heap (as in fusion_node): {kept}, "
        f"Fast DDS profile: {args.fastdds_profile or os.environ.get('FASTRTPS_DEFAULT_PROFILES_FILE') or 'default'}"
    )
    print(
        "\n| rig | views px | path | input Hz | output Hz | p50 ms | p99 ms | CPU p50 ms | n "
        "| target |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    scenes = {rig: build_scene(rig) for rig in args.rigs}
    configs = {
        (rig, r): load_perception_config(rig).replace(resolution=r)
        for rig in args.rigs
        for r in args.resolutions
    }
    ratios, breakdowns = [], []
    for rig, scene in scenes.items():
        for resolution in args.resolutions:
            timed, stages = in_process(
                scene, configs[rig, resolution], args.repeats, args.baseline, args.splat_baseline
            )
            for name, (wall, cpu) in timed.items():
                path = "in-process" if name == "today" else f"in-process, {name}"
                print(_row(rig, resolution, path, wall, "", None, cpu), flush=True)
            breakdowns.append(
                f"{rig} {resolution} px in-process, today's mean wall ms per set: "
                + ", ".join(f"{name} {ms:.1f}" for name, ms in stages.items())
            )
            ratios += [
                (
                    rig,
                    resolution,
                    name,
                    *(np.median(timed["today"][k]) / np.median(timed[name][k]) for k in (0, 1)),
                )
                for name in timed
                if name != "today"
            ]
    print("\n".join(breakdowns))
    for rig, resolution, name, wall, cpu in ratios:
        if name == args.baseline:
            print(
                f"{rig} {resolution} px in-process: p50 today / {name} = {wall:.2f}x wall, "
                f"{cpu:.2f}x CPU"
            )
            continue
        limit = SPLAT_COST_LIMIT[2] if (rig, resolution) == SPLAT_COST_LIMIT[:2] else None
        verdict = (
            f" (target <= {limit}x: {'met' if cpu <= limit else 'MISSED'} on CPU time)"
            if limit
            else ""
        )
        print(
            f"splatting cost, {rig} {resolution} px: p50 today / {name} = {wall:.2f}x wall, "
            f"{cpu:.2f}x CPU{verdict}"
        )
    if args.skip_node:
        return 0
    if shutil.which("ros2") is None:
        print("\nnode benchmark skipped: no `ros2` on PATH (source scripts/env.sh)")
        return 1
    with tempfile.TemporaryDirectory(prefix="bench_perception_") as tmp:
        trees = {"node": None}
        if args.baseline:
            trees[f"node, {args.baseline}"] = export_tree(args.baseline, Path(tmp) / "baseline")
        for rig, scene in scenes.items():
            for resolution in args.resolutions:
                rates = sorted({NODE_RATES[rig], CAPACITY_RATE})
                for path, tree in trees.items():
                    for result in through_node(
                        scene,
                        configs[rig, resolution],
                        rates,
                        args.duration,
                        Path(tmp),
                        args.fastdds_profile,
                        tree,
                    ):
                        if "error" in result:
                            print(
                                f"| {rig} | {resolution} | {path} | {result['rate']:g} "
                                f"| error: {result['error']} | | | | | |"
                            )
                            continue
                        rate_out = (
                            result["received"] / result["seconds"]
                            if result["seconds"] > 0
                            else 0.0
                        )
                        print(
                            _row(
                                rig,
                                resolution,
                                path,
                                np.array(result["latencies_ms"]),
                                f"{result['rate']:g}",
                                rate_out,
                            ),
                            flush=True,
                        )
    print(
        f"\nload average at the end: {os.getloadavg()[0]:.2f} "
        "(other jobs on the machine inflate these numbers)"
    )
    return 0
