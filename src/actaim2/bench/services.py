"""`actaim2 bench services`: the policy services as a client sees them, and the sim loop's pace.

* Round trips: ``policy_node`` and ``service_probe`` run as separate processes (``ros2 run``,
  a private ROS_DOMAIN_ID, loopback only). The probe publishes one set of views and times
  ``--calls`` calls of /sample_mode, then (a second probe) of /predict_keypose, from request to
  response: p50, p99. The node's CPU time per call (from /proc, load-independent) and its
  resident memory (RSS) afterwards are read too. The same against ``policy_node`` of the git
  revision ``--baseline`` (its sources exported from history, ``actaim2.bench.baseline``),
  alternating with today's for ``--rounds`` rounds (load drifts hit both alike), and the ratios
  of the p50s.
* In-process: :class:`PolicyModel` of today and of ``--baseline`` (its predictor and serving
  modules read from git, the same weights) answer the same requests in turn in this process,
  one torch thread: wall and CPU p50 per call, without DDS.
* Episodes: ``actaim2 launch sim_panda_ring5`` (SAPIEN, ring5 at 128 px, fusion, control, policy)
  and ``episode_runner``; wall time per episode from its JSONL records.

The checkpoint: ``--checkpoint``, else the committed one (``actaim2_ring5`` in
share/actaim2_policy/checkpoints), else an *untrained* checkpoint of the CPU default sizes
(train/configs/cpu_default.yaml, eps of 1920), written here: its inference costs what a trained
one of those sizes costs, but its keyposes mean nothing, so episodes then run the heuristic
sampler instead and the output says so. Targets on 2 cores: /predict_keypose p50 <= 15 ms,
/sample_mode p50 <= 5 ms, an episode <= 15 s. Other jobs on the machine inflate every figure:
the load average is printed before and after.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from actaim2.bench.baseline import BASELINE_REVISION, export_tree, node_command, python_path
from actaim2.bench.processes import private_ros_env, ros_run_command, start_logged, stop_group

TARGETS_MS = {"sample_mode": 5.0, "predict_keypose": 15.0}
EPISODE_TARGET_S = 15.0
UNTRAINED_EMBEDDING = 1920  # z of the default autoencoder on ring5: 5 cameras x 384


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--checkpoint",
        default="",
        help="checkpoint stem (default: the committed one, else untrained CPU-default sizes)",
    )
    parser.add_argument(
        "--perception", default="ring5", help="serving perception configuration (rig name or YAML)"
    )
    parser.add_argument("--calls", type=int, default=200, help="timed round trips per service")
    parser.add_argument(
        "--threads", type=int, default=1, help="policy_node torch_threads (its default: 1)"
    )
    parser.add_argument(
        "--episodes", type=int, default=3, help="sim-loop episodes to time (0: skip)"
    )
    parser.add_argument(
        "--workdir",
        type=Path,
        default=Path("runs/bench_services"),
        help="logs, records, temporary checkpoint",
    )
    parser.add_argument(
        "--baseline",
        default=BASELINE_REVISION,
        help="git revision whose policy_node and PolicyModel are timed beside today's ('' = skip)",
    )
    parser.add_argument(
        "--rounds",
        type=int,
        default=2,
        help="alternating rounds of today's and the baseline's node",
    )


def untrained_checkpoint(stem: Path, perception) -> Path:
    """A checkpoint with the CPU default training sizes and random weights (timing only)."""
    from actaim2.artifact import checkpoint
    from actaim2.models.predictor import ActionPredictor, PredictorConfig
    from actaim2.models.registry import build_selector
    from actaim2.models.selector_base import SelectorConfig
    from actaim2.perception.ortho_views import VIEWS
    from actaim2.train.config import load_config

    train = load_config("cpu_default")
    shape = {"views": len(VIEWS), "in_channels": len(perception.channels)}
    selector_dict = train.selector.to_dict()
    selector_config = SelectorConfig.from_dict(
        {**selector_dict, "z_dim": UNTRAINED_EMBEDDING, "obs": {**selector_dict["obs"], **shape}}
    )
    predictor_config = PredictorConfig.from_json(
        {
            **train.predictor,
            "embedding_dim": UNTRAINED_EMBEDDING,
            "image_size": perception.resolution,
            **shape,
        }
    )
    selector, predictor = build_selector(selector_config), ActionPredictor(predictor_config)
    meta = {
        "selector_config": selector_config.to_dict(),
        "predictor_config": predictor_config.to_json(),
        "perception": checkpoint.perception_record(perception),
        "dataset_digest": "untrained (timing only)",
        "lineage": {"init_from": None, "phases_done": []},
    }
    checkpoint.save(stem, checkpoint.policy_tensors(selector, predictor), meta)
    return stem


def save_views(path: Path, perception, seed: int = 0) -> None:
    """Views of the configuration's layout and digest (values in the renderer's ranges; cost does not depend on them)."""
    from actaim2.perception.ortho_views import VIEWS

    r = perception.resolution
    data = (
        np.random.default_rng(seed)
        .uniform(0.0, 1.0, (len(VIEWS), len(perception.channels), r, r))
        .astype(np.float32)
    )
    np.savez(
        path,
        data=data,
        views=np.array(VIEWS),
        channels=np.array(perception.channels),
        digest=perception.digest(),
    )


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def _pool(pooled: dict, result: dict) -> None:
    """Add one round's results to ``pooled``: round trips appended, CPU and RSS averaged."""
    rounds = pooled.get("rounds", 0)
    for key, value in result.items():
        if isinstance(value, list):
            pooled.setdefault(key, []).extend(value)
        elif isinstance(value, float):
            pooled[key] = (pooled.get(key, 0.0) * rounds + value) / (rounds + 1)
        else:
            pooled[key] = value
    pooled["rounds"] = rounds + 1


def round_trips(
    stem: Path,
    perception_arg: str,
    perception,
    args: argparse.Namespace,
    workdir: Path,
    tree: Path | None = None,
) -> dict:
    """Per service: round trips (ms) and the node's CPU time per call (ms); the node's RSS (MB).
    ``tree``: run the policy_node of this exported revision instead of today's."""
    env = private_ros_env()
    views = workdir / "views.npz"
    save_views(views, perception)
    command = ros_run_command(
        "actaim2_policy",
        "policy_node",
        {"checkpoint": stem, "perception_config": perception_arg, "torch_threads": args.threads},
    )
    if tree is not None:
        command = node_command(tree, "actaim2_policy", "policy_node", command[4:])
    node = start_logged(
        command,
        env if tree is None else dict(env, PYTHONPATH=python_path(tree)),
        workdir / "policy_node.log",
    )
    result: dict = {}
    try:
        for service in ("sample_mode", "predict_keypose"):
            summary = workdir / f"{service}.json"
            summary.unlink(missing_ok=True)
            probe = subprocess.run(
                ros_run_command(
                    "actaim2_policy",
                    "service_probe",
                    {
                        "views_file": views,
                        "service": service,
                        "calls": args.calls,
                        "summary_file": summary,
                        "node_pid": node.pid,
                    },
                ),  # `ros2 run` execs the node: the same pid
                env=env,
                capture_output=True,
                text=True,
                timeout=600,
            )
            if probe.returncode != 0 or not summary.exists():
                raise RuntimeError(
                    f"service_probe failed:\n{probe.stdout[-2000:]}{probe.stderr[-2000:]}\n"
                    f"policy_node log:\n{(workdir / 'policy_node.log').read_text()[-2000:]}"
                )
            timed = json.loads(summary.read_text())
            result[service] = timed["ms"]
            result[f"{service}_cpu_ms"] = timed["node_cpu_ms"]
            result["served"] = timed["served"]
        result["rss_mb"] = _rss_mb(node.pid)
    finally:
        stop_group(node)
    return result


def episode_times(
    stem: Path | None, perception_arg: str, args: argparse.Namespace, workdir: Path
) -> dict:
    """Wall time per episode of the sim loop; the learned policy when ``stem``, else the heuristic sampler."""
    import yaml

    from actaim2.launch.cli import default_graphs_file

    graphs = yaml.safe_load(default_graphs_file().read_text())
    graph = graphs["sim_panda_ring5"]
    if stem is not None:
        for node in graph["nodes"]:
            if node["executable"] == "policy_node":
                node["parameters"] = {
                    **node.get("parameters", {}),
                    "checkpoint": str(stem),
                    "perception_config": perception_arg,
                }
    graphs_file = workdir / "graphs.yaml"
    graphs_file.write_text(yaml.safe_dump({"sim_panda_ring5": graph}))
    env = private_ros_env()
    records = workdir / "episodes.jsonl"
    launch = start_logged(
        [
            sys.executable,
            "-m",
            "actaim2.cli",
            "launch",
            "sim_panda_ring5",
            "--graphs",
            str(graphs_file),
            "--logs",
            str(workdir / "graph"),
        ],
        env,
        workdir / "launch.log",
    )
    keyposes = "policy" if stem is not None else "sampler"
    try:
        runner = subprocess.run(
            ros_run_command(
                "actaim2_policy",
                "episode_runner",
                {
                    "episodes": args.episodes,
                    "keyposes": keyposes,
                    "jsonl_file": records,
                    "server_timeout": 180.0,
                },
            ),
            env=env,
            capture_output=True,
            text=True,
            timeout=300 + 120 * args.episodes,
        )
    finally:
        stop_group(launch, timeout=60.0)
    (workdir / "episode_runner.log").write_text(runner.stdout + runner.stderr)
    if runner.returncode != 0:
        raise RuntimeError(
            f"episode_runner failed (log {workdir / 'episode_runner.log'}):\n"
            f"{runner.stderr[-2000:]}"
        )
    rows = [json.loads(line) for line in records.read_text().splitlines()]
    return {
        "keyposes": keyposes,
        "seconds": [r["seconds"] for r in rows],
        "successes": sum(r["success"] for r in rows),
        "phases": [len(r["phases"]) for r in rows],
    }


def in_process(
    stem: Path, perception, calls: int, baseline: str
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{"<service>" / "<service>, <baseline>": (wall ms, CPU ms)} of ``calls`` alternating
    in-process calls."""
    import time

    import torch

    from actaim2.artifact.serving import DEFAULT_SERVING
    from actaim2.bench.baseline import modules_at
    from actaim2.policy.inference import PolicyModel
    from actaim2.policy.views import Views

    torch.set_num_threads(1)
    models = {"": PolicyModel.load(stem, perception, "cpu")}
    if baseline:
        # The baseline's serving loaded checkpoints through its own train.checkpoint (today's
        # is artifact.checkpoint): it loads from the revision too.
        old = modules_at(baseline, ["actaim2.train.checkpoint", "actaim2.models.predictor", "actaim2.policy.inference"])
        model = old["actaim2.policy.inference"].PolicyModel.load(stem, perception, "cpu")
        if (
            model.predictor is not None
        ):  # the checkpoint loader builds today's class: the same weights in the old one
            predictor = old["actaim2.models.predictor"].ActionPredictor(model.predictor.config)
            predictor.load_state_dict(model.predictor.state_dict())
            model.predictor = predictor.eval()
        models[f", {baseline}"] = model
    data = (
        np.random.default_rng(0)
        .uniform(
            0.0, 1.0, (5, len(perception.channels), perception.resolution, perception.resolution)
        )
        .astype(np.float32)
    )
    views = Views(0, data)
    for model in models.values():
        model.warm_up()
    eps = models[""].sample_mode(views, 0, 0).eps
    requests = {
        "sample_mode": lambda m, k: m.sample_mode(views, k % max(m.clusters, 1), k),
        "predict_keypose": lambda m, k: m.predict_keypose(
            views, eps, k % 4, k % 4 == 3, DEFAULT_SERVING.keypose_alternatives
        ),
    }
    times = {f"{name}{suffix}": ([], []) for name in requests for suffix in models}
    for k in range(calls):
        for name, call in requests.items():
            for suffix, model in list(models.items())[
                :: 1 if k % 2 else -1
            ]:  # each goes first in turn (caches)
                wall, cpu = time.perf_counter(), time.process_time()
                call(model, k)
                times[f"{name}{suffix}"][0].append((time.perf_counter() - wall) * 1e3)
                times[f"{name}{suffix}"][1].append((time.process_time() - cpu) * 1e3)
    return {key: (np.array(wall), np.array(cpu)) for key, (wall, cpu) in times.items()}


def _ms_row(name: str, values: list[float], cpu_ms: float, target: float | None) -> str:
    p50, p99 = np.percentile(values, 50), np.percentile(values, 99)
    verdict = (
        "" if target is None else f"p50 <= {target:g} ms: {'met' if p50 <= target else 'MISSED'}"
    )
    return (f"| {name} round trip | {p50:.1f} ms | {p99:.1f} ms | {cpu_ms:.1f} ms | {len(values)} "
            f"| {verdict} |")


def main(args: argparse.Namespace) -> int:
    from actaim2.perception.config import load_perception_config
    from actaim2.policy.locate import COMMITTED, installed_folders, resolve_checkpoint

    workdir = args.workdir.resolve()
    workdir.mkdir(parents=True, exist_ok=True)
    perception = load_perception_config(args.perception)
    load = os.getloadavg()
    print(
        f"# actaim2 bench services ({os.cpu_count()} CPUs, "
        f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; "
        f"policy_node torch_threads {args.threads})"
    )
    trained: Path | None = None
    try:
        trained = resolve_checkpoint(args.checkpoint or COMMITTED, installed_folders())
        stem = trained
        print(f"checkpoint: {stem}")
    except FileNotFoundError as exc:
        if args.checkpoint:
            print(f"actaim2 bench services: {exc}", file=sys.stderr)
            return 2
        stem = untrained_checkpoint(workdir / "untrained_cpu_default", perception)
        print(
            f"checkpoint: none committed yet ({exc}); timing an UNTRAINED checkpoint of the CPU "
            f"default sizes ({stem})"
        )
    result, baseline = {}, {} if args.baseline else None
    with tempfile.TemporaryDirectory(prefix="bench_services_") as tmp:
        tree = export_tree(args.baseline, Path(tmp)) if args.baseline else None
        (workdir / "baseline").mkdir(exist_ok=True)
        for _ in range(max(args.rounds, 1) if args.baseline else 1):
            _pool(result, round_trips(stem, args.perception, perception, args, workdir))
            if tree is not None:
                _pool(
                    baseline,
                    round_trips(
                        stem, args.perception, perception, args, workdir / "baseline", tree
                    ),
                )
    print(f"served: {result['served']}\n")
    timed = in_process(stem, perception, args.calls, args.baseline)
    rows = ["| measurement | p50 | p99 | CPU per call | n | target |", "|---|---|---|---|---|---|"]
    for key, (wall, cpu) in timed.items():
        rows.append(
            f"| in-process {key} | {np.percentile(wall, 50):.1f} ms "
            f"| {np.percentile(wall, 99):.1f} ms | "
            f"{np.percentile(cpu, 50):.1f} ms | {len(wall)} | |"
        )
    for name in ("sample_mode", "predict_keypose"):
        rows.append(_ms_row(f"/{name}", result[name], result[f"{name}_cpu_ms"], TARGETS_MS[name]))
        if baseline is not None:
            rows.append(
                _ms_row(
                    f"/{name}, policy_node of {args.baseline}",
                    baseline[name],
                    baseline[f"{name}_cpu_ms"],
                    None,
                )
            )
    rows.append(f"| policy_node RSS after the calls | {result['rss_mb']:.0f} MB | | | | |")
    if baseline is not None:
        services = ("sample_mode", "predict_keypose")
        old = {name: timed[f"{name}, {args.baseline}"] for name in services}
        inside = ", ".join(
            f"{name} {np.median(timed[name][0]) / np.median(old[name][0]):.2f}x "
            f"(CPU {np.median(timed[name][1]) / np.median(old[name][1]):.2f}x)"
            for name in old
        )
        print(f"in-process p50 today / PolicyModel of {args.baseline}: {inside}")
        ratios = ", ".join(
            f"/{name} {np.median(result[name]) / np.median(baseline[name]):.2f}x "
            f"(node CPU {result[f'{name}_cpu_ms'] / baseline[f'{name}_cpu_ms']:.2f}x)"
            for name in ("sample_mode", "predict_keypose")
        )
        print(f"p50 today / policy_node of {args.baseline}: {ratios}")
    if args.episodes > 0:
        episodes = episode_times(trained, args.perception, args, workdir)
        seconds = episodes["seconds"]
        verdict = "met" if np.median(seconds) <= EPISODE_TARGET_S else "MISSED"
        source = (
            "learned policy"
            if episodes["keyposes"] == "policy"
            else "heuristic sampler: no trained checkpoint"
        )
        rows.append(
            f"| episode wall time ({source}; phases run {episodes['phases']}, "
            f"{episodes['successes']} successes) | {np.median(seconds):.1f} s "
            f"| max {max(seconds):.1f} s | | {len(seconds)} "
            f"| <= {EPISODE_TARGET_S:g} s: {verdict} |"
        )
    print("\n".join(rows))
    load = os.getloadavg()
    print(
        f"\nload average at the end: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} "
        "(other jobs on the machine inflate these numbers)"
    )
    return 0
