"""`actaim2 bench throughput`: where evaluation samples' and collection trajectories' time goes.

Real PartNet-Mobility objects of one split (default ``val`` of ``<objects>/splits.yaml``), in
one process on one torch thread, through the code the commands run: evaluation samples by
:class:`actaim2.eval.worker.EvalWorker` (the checkpoint's policy, one cluster per slot in turn),
collection trajectories by :class:`actaim2.data.collect.CollectionWorker` (the random and the
heuristic-grasp samplers in turn). Objects are visited in turn, so every sample loads its object
as the commands do. One evaluation sample and one trajectory run first, untimed: the
checkpoint's load and the renderer's shader compilation are paid once per worker, not per sample.

The counts printed with them include the runs that moved a part by more than ``MOVED`` of its
range: the objects are physically there for both paths.

Each run records an :class:`actaim2.profiling.Profile`: the sections the library marks
(physics steps, rendering, object loading, depth back-projection, fusion, the object cloud's
support removal, the self-filter, splatting the views, action sampling, IK, collision checks,
planning, model forward, trajectory encoding) in exclusive wall time, and the rest of the wall
time as "Python and the rest" (loop bookkeeping, outcome, conversions). Rendering is also
given per observation and per camera. Hulls come from ``--hull-cache``
(default: the default cache); a collision mesh without an entry loads as one hull, and the
output says how many meshes of the objects have none.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

DEFAULT_OBJECTS = Path("../shared/partnet")
MOVED = 0.05  # a run "moved a part" when some DoF changed by more than this share of its range
OTHER = "Python and the rest"
ORDER = (
    "physics",
    "render",
    "object load",
    "back-projection",
    "fusion",
    "object cloud",
    "self-filter",
    "splatting",
    "sampling",
    "IK",
    "collision checks",
    "planning",
    "model forward",
    "encoding",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--objects", type=Path, default=DEFAULT_OBJECTS, help="PartNet-Mobility folders"
    )
    parser.add_argument(
        "--splits", type=Path, help="object splits YAML (default: <objects>/splits.yaml)"
    )
    parser.add_argument("--split", default="val", help="the split whose objects are used")
    parser.add_argument("--samples", type=int, default=10, help="evaluation samples (0: skip)")
    parser.add_argument(
        "--trajectories", type=int, default=10, help="collection trajectories (0: skip)"
    )
    parser.add_argument(
        "--checkpoint", default="actaim2_ring5", help="policy checkpoint (name or stem)"
    )
    parser.add_argument(
        "--hull-cache", type=Path, help="hull cache folder (default: the default cache)"
    )
    parser.add_argument("--render-path", default="auto", choices=["auto", "sapien", "raycast"])


def split_folders(objects: Path, splits: Path, split: str) -> list[Path]:
    import yaml

    names = sorted(
        str(name) for name, s in (yaml.safe_load(splits.read_text()) or {}).items() if s == split
    )
    folders = [objects / name for name in names if (objects / name / "mobility.urdf").is_file()]
    if not folders:
        raise ValueError(f"no object of split '{split}' ({splits}) under {objects}")
    return folders


def hull_coverage(folders: list[Path], cache) -> tuple[int, int]:
    """(collision mesh files with a cache entry, all of them) over ``folders``."""
    from actaim2.sim.objects.partnet import read_object_folder

    meshes = [m for f in folders for m in read_object_folder(f).collision_mesh_files()]
    return sum(cache.lookup(m) is not None for m in meshes), len(meshes)


def evaluation_runs(
    folders: list[Path], args: argparse.Namespace, render_path: str
) -> tuple[list, dict]:
    """(one Profile per timed sample with its wall seconds, counts) of ``args.samples`` samples."""
    from actaim2.eval.checkpoints import perception_of
    from actaim2.eval.evalset import EvalObject
    from actaim2.eval.tasks import EvalTask
    from actaim2.eval.worker import EvalWorker, WorkerSetup
    from actaim2.policy.locate import installed_folders, resolve_checkpoint
    from actaim2.sim.objects.hulls import HullCache
    from actaim2.sim.objects.model import read_meta

    stem = resolve_checkpoint(args.checkpoint, installed_folders())
    perception = perception_of(stem)
    setup = WorkerSetup(
        "panda",
        perception.rig,
        render_path,
        tuple(perception.center),
        float(perception.half_extent),
        {"actaim2": str(stem)},
    )
    worker = EvalWorker(setup)
    worker.env.hulls = HullCache(args.hull_cache)
    clusters = worker.source("actaim2").model.clusters
    objects = [
        EvalObject(args.split, str(read_meta(f).get("model_cat", "unknown")), -1, str(f.resolve()))
        for f in folders
    ]

    def task(i: int) -> EvalTask:
        slot = i // len(objects)
        return EvalTask("actaim2", objects[i % len(objects)], slot, slot % clusters, clusters)

    worker.run(task(len(objects) * clusters))  # untimed: first render, lazy imports
    runs, counts = [], {"success": 0, "moved": 0, "error": 0}
    for i in range(args.samples):
        record, profile, seconds = _recorded(worker.run, task(i))
        runs.append((profile, seconds))
        counts["success"] += bool(record.get("success"))
        counts["moved"] += record.get("largest_change", 0.0) > MOVED
        counts["error"] += "error" in record
    return runs, counts


def collection_runs(
    folders: list[Path], args: argparse.Namespace, render_path: str, out: Path
) -> tuple[list, dict]:
    """(one Profile per timed trajectory with its wall seconds, counts)."""
    from actaim2.data.collect import CollectConfig, CollectionWorker, Task, derive_seed
    from actaim2.data.real_objects import FolderObject
    from actaim2.data.storage import EncodedTrajectory
    from actaim2.sim.objects.partnet import read_object_folder

    infos = [read_object_folder(f) for f in folders]
    config = CollectConfig(
        out=out,
        objects=(),
        per_object={},
        render_path=render_path,
        hull_cache=args.hull_cache,
        folders=tuple(FolderObject(str(i.folder), i.category, args.split) for i in infos),
    )
    worker = CollectionWorker(config)

    def task(i: int) -> Task:
        info, sampler = infos[i % len(infos)], ("random", "grasp")[(i // len(infos)) % 2]
        return Task(
            f"bench_{info.object_id}_{sampler}_{i}",
            info.category,
            -1,
            args.split,
            sampler,
            i,
            derive_seed(0, info.object_id, i),
            folder=str(info.folder),
        )

    worker.run(task(2 * len(infos)))  # untimed: first render, lazy imports
    runs, counts = [], {"stored": 0, "moved": 0, "given up": 0}
    for i in range(args.trajectories):
        result, profile, seconds = _recorded(worker.run, task(i))
        runs.append((profile, seconds))
        stored = isinstance(result, EncodedTrajectory)
        counts["stored" if stored else "given up"] += 1
        counts["moved"] += stored and max(map(abs, result.entry["dof_change"]), default=0.0) > MOVED
    return runs, counts


def _recorded(run, task):
    from actaim2.profiling import Profile, recording

    profile = Profile()
    with recording(profile):
        started = time.perf_counter()
        result = run(task)
        seconds = time.perf_counter() - started
    return result, profile, seconds


def summary(runs: list) -> tuple[float, dict[str, tuple[float, float]]]:
    """(mean wall ms per run, {section: (mean ms per run, mean entries per run)}), the rest of the
    wall time as OTHER."""
    n = len(runs)
    wall = sum(s for _, s in runs) * 1e3 / n
    names = {name for p, _ in runs for name in p.seconds}
    rows = {
        name: (
            sum(p.seconds.get(name, 0.0) for p, _ in runs) * 1e3 / n,
            sum(p.calls.get(name, 0) for p, _ in runs) / n,
        )
        for name in names
    }
    rows[OTHER] = (wall - sum(ms for ms, _ in rows.values()), float("nan"))
    return wall, rows


def print_table(columns: dict[str, list], cameras: int) -> None:
    """One row per section, a (ms, share, entries) column group per kind of run."""
    summaries = {kind: summary(runs) for kind, runs in columns.items() if runs}
    names = [n for n in ORDER if any(n in rows for _, rows in summaries.values())]
    names += sorted({n for _, rows in summaries.values() for n in rows} - set(names) - {OTHER}) + [
        OTHER
    ]
    head = " | ".join(f"{k}: ms | share | entries" for k in summaries)
    print(f"\n| section | {head} |")
    print("|---|" + "---|---|---|" * len(summaries))
    for name in names:
        cells = []
        for wall, rows in summaries.values():
            ms, calls = rows.get(name, (0.0, 0.0))
            cells.append(
                f"{ms:.0f} | {100 * ms / wall:.1f} % | {'' if calls != calls else f'{calls:.1f}'}"
            )
        print(f"| {name} | {' | '.join(cells)} |")
    totals = " | ".join(f"**{wall:.0f}** | 100 % | " for wall, _ in summaries.values())
    print(f"| **wall per run** | {totals} |")
    for kind, (_, rows) in summaries.items():
        ms, calls = rows.get("render", (0.0, 0.0))
        if calls:
            print(
                f"{kind}: rendering {ms / calls:.0f} ms per observation ({calls:.1f} per run), "
                f"{ms / calls / cameras:.1f} ms per camera ({cameras} cameras)"
            )


def main(args: argparse.Namespace) -> int:
    import torch

    from actaim2.sim.cameras import make_rig
    from actaim2.sim.objects.hulls import HullCache
    from actaim2.sim.objects.sizing import WORKSPACE_CENTER
    from actaim2.sim.render_path import resolve_render_path

    torch.set_num_threads(1)
    folders = split_folders(args.objects, args.splits or args.objects / "splits.yaml", args.split)
    render_path = resolve_render_path(args.render_path)
    cache = HullCache(args.hull_cache)
    cached, meshes = hull_coverage(folders, cache)
    print(
        f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at start; "
        f"render path {render_path}; {len(folders)} '{args.split}' objects "
        f"({', '.join(f.name for f in folders)}); hull cache {cache.root}: {cached} of {meshes} "
        f"collision mesh files have an entry, the others load as one hull each"
    )
    evaluation, counts = (
        evaluation_runs(folders, args, render_path) if args.samples > 0 else ([], {})
    )
    if evaluation:
        print(
            f"evaluation: {len(evaluation)} samples of actaim2 ({args.checkpoint}), "
            f"{counts['success']} successes, {counts['moved']} moved a part by more than "
            f"{MOVED:.0%}, {counts['error']} errors; "
            f"load average {os.getloadavg()[0]:.2f}"
        )
    collection: list = []
    if args.trajectories > 0:
        with tempfile.TemporaryDirectory(prefix="actaim2-bench-throughput-") as tmp:
            collection, counts = collection_runs(folders, args, render_path, Path(tmp))
        print(
            f"collection: {len(collection)} trajectories (random and grasp samplers in turn), "
            f"{counts['stored']} stored, {counts['moved']} moved a part by more than {MOVED:.0%}, "
            f"{counts['given up']} given up; "
            f"load average {os.getloadavg()[0]:.2f}"
        )
    cameras = len(make_rig("ring5", WORKSPACE_CENTER))
    print_table({"evaluation sample": evaluation, "collection trajectory": collection}, cameras)
    for kind, runs in (("evaluation", evaluation), ("collection", collection)):
        if runs:
            wall, _ = summary(runs)
            print(
                f"{kind}: {1e3 / wall:.2f} per s in one process "
                f"({2e3 / wall:.2f} per s with 2 workers if they scaled perfectly)"
            )
    print(
        f"load average at the end: {os.getloadavg()[0]:.2f} "
        "(other jobs on the machine inflate wall times)"
    )
    return 0
