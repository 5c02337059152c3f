"""`actaim2 evaluate`: the paper's SSR and Mode SSR tables on the simulator, with the baselines.

Examples:
    actaim2 evaluate --out runs/eval --checkpoint runs/cpu/policy --data data/ds          # full (<= 3.5 h, resumable)
    actaim2 evaluate --out runs/eval-quick --quick --checkpoint runs/cpu/policy --data data/ds
    actaim2 evaluate --out runs/eval --checkpoint runs/cpu/policy --vqvae runs/vq/policy --cvae runs/cvae/policy \\
        --data data/ds --objects ~/partnet-mobility/148 --workers 2
    actaim2 evaluate --out runs/eval --checkpoint runs/cpu/policy --ray auto --workers 16          # a Ray cluster
    actaim2 evaluate --out runs/eval --checkpoint runs/cpu/policy --data data/ds --per-group 16    # Mode SSR on 4x the samples
    actaim2 evaluate --out runs/val --checkpoint runs/pm/policy --data data/pm --catalogue partnet
    actaim2 evaluate --out runs/test --checkpoint runs/s0/policy --data data/pm \\
        --catalogue partnet --splits test_unseen_instance,test_unseen_category --per-group 8 \\
        --final                                   # test splits: under results/protocol.lock

Rows: ActAIM2 (--checkpoint), Goal-RVT (--goal-rvt, default <checkpoint folder>/goal_rvt, with
the dataset's encoder), VQVAE-RVT (--vqvae), ActAIM's CVAE (--cvae), Data Collection (--data:
the GMM-adaptive sampler fitted on the dataset's exploration trajectories), Random (always),
and ActAIM2's input ablations (--ablation-depth, --ablation-single-view: a predictor retrained
on less input, sampled as ActAIM2).
Interrupt it at any time: the same command resumes, skipping finished samples. Tables go to
<out>/tables.md with the command and the checkpoints' digests; records to <out>/results.jsonl.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from actaim2.data.collect_cli import add_catalogue_arguments
from actaim2.eval.presets import DATA_COLLECTION_EXPLORATION
from actaim2.protocol.arguments import add_protocol_arguments, splits_files

if TYPE_CHECKING:
    from actaim2.eval.presets import Preset


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, required=True, help="results folder (created, or resumed if it exists)")
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--smoke", action="store_true", help="3 objects, 1 sample per cluster (CI, <= 2 min)")
    size.add_argument("--quick", action="store_true", help="15 objects (one per category and split), 1 sample per cluster (<= 10 min)")
    parser.add_argument("--per-group", type=int, metavar="N",
                        help="samples per cluster, code and pseudo-cluster (ActAIM2, its ablations, VQVAE-RVT, Data "
                             "Collection) instead of the size's (full: 4): narrower Mode SSR intervals; resuming a run "
                             "with a larger N adds repetitions")
    parser.add_argument("--checkpoint", type=Path, help="ActAIM2 policy checkpoint (stem, e.g. runs/cpu/policy)")
    parser.add_argument("--goal-rvt", type=Path, help="Goal-RVT checkpoint (default: goal_rvt beside --checkpoint, if present)")
    parser.add_argument("--vqvae", type=Path, help="VQVAE-RVT policy checkpoint")
    parser.add_argument("--cvae", type=Path, help="ActAIM (CVAE) policy checkpoint")
    parser.add_argument("--ablation-depth", type=Path, help="ablation: policy checkpoint with a depth-only predictor "
                                                            "(train config ablation_depth)")
    parser.add_argument("--ablation-single-view", type=Path, help="ablation: policy checkpoint with a single-view predictor "
                                                                  "(train config ablation_single_view)")
    parser.add_argument("--data", type=Path, help="the training dataset: Data Collection's GMMs and Goal-RVT's encoder E")
    parser.add_argument("--encoder", type=Path, help="Goal-RVT's encoder E (default: the dataset's encoder.pt)")
    parser.add_argument("--data-collection-exploration", type=int, default=DATA_COLLECTION_EXPLORATION, metavar="N",
                        help="Data Collection on objects --data does not hold: first collect N exploration trajectories "
                             "on each (half random, half heuristic grasp) into <out>/data_collection, labelled by "
                             "--data's success label; 0 leaves such objects out of its row")
    parser.add_argument("--methods", default="", help="only these rows (comma separated: actaim2, data_collection, random, "
                                                      "goal_rvt, vqvae_rvt, actaim_cvae, actaim2_depth, actaim2_single_view)")
    add_catalogue_arguments(parser)
    parser.add_argument("--splits", help="the catalogue's splits to evaluate on ('' = none, with "
                                         "--objects; default: generated train_seen,"
                                         "train_unseen_instance,heldout_category; partnet val)")
    add_protocol_arguments(parser)
    parser.add_argument("--objects", type=Path, help="PartNet-Mobility folder(s) (a folder with mobility.urdf, or a folder of them): an extra split")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (0 = in this process); Ray actors with --ray")
    parser.add_argument("--ray", metavar="ADDRESS", help="run the samples on Ray actors: auto, ray://host:port, or local")
    parser.add_argument("--robot", default="panda", help="robot preset or YAML")
    parser.add_argument("--perception", default="ring5", help="rig configuration when no checkpoint is given (samplers only)")
    parser.add_argument("--render-path", choices=["sapien", "raycast"], help="override the configuration's render path")
    parser.add_argument("--allow-raycast", action="store_true", help="without a Vulkan device, render by ray casting instead of refusing")
    parser.add_argument("--figures", type=int, default=2, metavar="N",
                        help="embedding (PCA) and heatmap figures of ActAIM2 on the first N objects (0 = none)")
    parser.add_argument("--videos", type=int, metavar="N",
                        help="GIFs of one ActAIM2 episode per cluster on the first N objects, in <out>/videos "
                             "(default: 2, none with --smoke)")
    parser.add_argument("--grounding", metavar="CATEGORY:INSTANCE",
                        help="run the interaction-mode grounding experiment on this object instead of the tables "
                             "(ActAIM2: bandit over clusters; --cvae / --vqvae: CEM over their embedding)")
    parser.add_argument("--grounding-iterations", type=int, default=50, help="samples per grounding run")
    parser.add_argument("--grounding-seeds", type=int, default=5, help="grounding runs per method and target")
    parser.add_argument("--hand-half-turn", action=argparse.BooleanOptionalAction, default=None,
                        help="plan each INIT/REACH keypose or its half turn about the approach axis, whichever the planner "
                             "accepts (nearer the current tcp orientation first; default on, as control_node); "
                             "recorded in run.json")
    parser.add_argument("--keypose-alternatives", type=int, default=None,
                        help="fallback rotations a policy row gives with each keypose, executed in turn when the planner "
                             "refuses it (default as policy_node); recorded in run.json")
    parser.add_argument("--mode-guidance", type=float, default=None, metavar="W",
                        help="mode guidance weight of a policy row's translation (models/mode_guidance.py; default as "
                             "policy_node, 0 = off); recorded in run.json")
    parser.add_argument("--reproduce", type=Path, metavar="DIR",
                        help="re-run a seeded choice of DIR's samples (an evaluation folder, or a committed record "
                             "under results/) with this command's settings and say how many outcomes agree "
                             "(<out>/reproduction.json)")
    parser.add_argument("--reproduce-samples", type=int, default=40, metavar="N",
                        help="samples re-run with --reproduce (default 40)")
    parser.add_argument("--noise-scale", type=float, default=None, metavar="S",
                        help="spread of a policy row's mode draws relative to its selector's (ModeSelector.sample; "
                             "default as policy_node, 1 = as trained, 0 = each cluster's noise-free eps); recorded in run.json")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _preset(args: argparse.Namespace) -> Preset:
    from actaim2.eval.presets import PRESETS

    preset = PRESETS["smoke" if args.smoke else "quick" if args.quick else "full"]
    return preset if args.per_group is None else preset.with_per_group(args.per_group)


def _render_path(perception, args: argparse.Namespace) -> str:
    """The configuration's render path, or ray casting when asked for (or allowed, without Vulkan)."""
    from actaim2.sim.render_path import vulkan_device_error

    requested = args.render_path or perception.render_path
    if requested == "raycast":
        return "raycast"
    error = vulkan_device_error()
    if error is None:
        return "sapien"
    if not args.allow_raycast:
        raise ValueError(f"no Vulkan device for SAPIEN rendering ({error}); pass --allow-raycast to evaluate on ray-cast "
                         f"pictures (the models were trained on {perception.render_path} pictures)")
    print(f"actaim2 evaluate: no Vulkan device ({error}): ray-cast pictures, as --allow-raycast permits", file=sys.stderr)
    return "raycast"


def _methods(args: argparse.Namespace) -> tuple[dict[str, Path], list[str]]:
    """(method -> checkpoint stem, the methods to run), with the reason for every row left out."""
    from actaim2.artifact.checkpoint import paths
    from actaim2.eval.methods import METHODS

    checkpoints = {"actaim2": args.checkpoint, "goal_rvt": args.goal_rvt, "vqvae_rvt": args.vqvae, "actaim_cvae": args.cvae,
                   "actaim2_depth": args.ablation_depth, "actaim2_single_view": args.ablation_single_view}
    if checkpoints["goal_rvt"] is None and args.checkpoint is not None and paths(args.checkpoint.parent / "goal_rvt")[1].exists():
        checkpoints["goal_rvt"] = args.checkpoint.parent / "goal_rvt"
    available = [m for m, stem in checkpoints.items() if stem is not None]
    if checkpoints["goal_rvt"] is not None and _encoder(args, checkpoints["goal_rvt"]) is None:
        available.remove("goal_rvt")
        print("actaim2 evaluate: Goal-RVT left out: its encoder E is not beside its checkpoint; it needs --data "
              "(the encoder of its embeddings) or --encoder", file=sys.stderr)
    if args.data is not None:
        available.append("data_collection")
    available.append("random")
    wanted = [m for m in args.methods.split(",") if m] or list(METHODS)
    unknown = [m for m in wanted if m not in METHODS]
    if unknown:
        raise ValueError(f"unknown method(s) {unknown}; known: {list(METHODS)}")
    missing = [m for m in wanted if m not in available]
    if args.methods and missing:
        raise ValueError(f"cannot run {missing}: " + "; ".join(f"{m} needs {METHODS[m].needs}" for m in missing))
    return {m: Path(s) for m, s in checkpoints.items() if s is not None}, [m for m in METHODS if m in wanted and m in available]


def _encoder(args: argparse.Namespace, goal_rvt: Path) -> Path | None:
    """Goal-RVT's encoder E: --encoder, else the one beside its checkpoint, else the dataset's."""
    from actaim2.artifact.checkpoint import encoder_path
    from actaim2.data.labelling import dataset_encoder

    if args.encoder is not None:
        return args.encoder
    if encoder_path(goal_rvt).is_file():
        return encoder_path(goal_rvt)
    return dataset_encoder(args.data) if args.data is not None else None


def main(args: argparse.Namespace) -> int:
    from actaim2.artifact.serving import DEFAULT_SERVING, check_noise_scale
    from actaim2.control.planner import POLICY_PLANNER
    from actaim2.data.real_objects import partnet_root
    from actaim2.data.splits import GENERATED, catalogue
    from actaim2.eval.checkpoints import describe, perception_of
    from actaim2.eval.data_collection import (
        EXPLORATION_DIR,
        data_collection_samplers,
        explored_samplers,
    )
    from actaim2.eval.evalset import (
        EVAL_SET_VERSION,
        catalogue_objects,
        folder_objects,
        partnet_objects,
    )
    from actaim2.eval.methods import ABLATIONS, PSEUDO_GROUPING, ablation_problem
    from actaim2.eval.reproduce import REPRODUCTION_FILE, agreement, choose, reference_records
    from actaim2.eval.results import ResultLog, RunMismatchError, check_run
    from actaim2.eval.tables import report
    from actaim2.eval.tasks import plan_tasks
    from actaim2.eval.worker import EvalWorker, WorkerSetup
    from actaim2.parallel import ray_available
    from actaim2.perception.config import load_perception_config
    from actaim2.protocol.lock import append_ledger, guarded_ids, protected, read_ledger
    from actaim2.protocol.lock import check_run as check_protocol

    half_turn = POLICY_PLANNER.hand_half_turn if args.hand_half_turn is None else args.hand_half_turn
    alternatives = DEFAULT_SERVING.keypose_alternatives if args.keypose_alternatives is None else args.keypose_alternatives
    guidance = DEFAULT_SERVING.mode_guidance if args.mode_guidance is None else args.mode_guidance
    noise_scale = DEFAULT_SERVING.noise_scale if args.noise_scale is None else args.noise_scale
    try:
        preset = _preset(args)
        ray_problem = ray_available() if args.ray else None
        if ray_problem:
            raise ValueError(f"--ray: {ray_problem}")
        if alternatives < 0:
            raise ValueError(f"--keypose-alternatives {alternatives} is negative")
        if not guidance >= 0.0:
            raise ValueError(f"--mode-guidance {guidance} is not a weight >= 0")
        check_noise_scale(noise_scale, "--noise-scale")
        stems, methods = _methods(args)
        described = {m: describe(stems[m]) for m in methods if m in stems}
        for m in (m for m in ABLATIONS if m in described):
            problem = ablation_problem(m, described[m]["predictor_inputs"], described[m]["predictor_view"])
            if problem:
                raise ValueError(f"{m}: checkpoint {stems[m]}: {problem}")
        configs = {m: perception_of(stems[m]) for m in described}
        perception = next(iter(configs.values())) if configs else load_perception_config(args.perception)
        for m, c in configs.items():
            if (c.rig, c.center, c.half_extent) != (perception.rig, perception.center, perception.half_extent):
                raise ValueError(f"{m}'s checkpoint was trained on rig {c.rig} (cube {c.center}, {c.half_extent}), "
                                 f"{next(iter(configs))}'s on {perception.rig} ({perception.center}, {perception.half_extent})")
        chosen = catalogue(args.catalogue)
        splits = chosen.default_evaluate
        if args.splits is not None:
            splits = chosen.check_splits(tuple(s for s in args.splits.split(",") if s), "--splits")
        if chosen is GENERATED:
            objects = catalogue_objects(splits, preset.instances_per_category, preset.categories)
        else:
            objects = partnet_objects(partnet_root(args.partnet_root), splits,
                                      preset.instances_per_category, preset.categories)
        if args.objects is not None:
            objects += folder_objects(args.objects)
        if not objects:
            raise ValueError("no object to evaluate on: give --splits or --objects")
        given = [args.objects] if args.objects is not None else []
        named = [(o.split, o.object_id if o.folder else "") for o in objects]
        guarded = protected(named, guarded_ids(splits_files(args, given)))
        locked = [described["actaim2"]["weights_sha256"]] if "actaim2" in described else []
        if args.final and preset.counts.per_cluster != preset.counts.baseline_per_group:
            raise ValueError("--final: ActAIM2 and the grouped baselines need as many samples per "
                             "group: pass --per-group N")
        lock = check_protocol("evaluate", guarded, args.final, args.lock, locked, EVAL_SET_VERSION,
                              preset.counts.per_cluster)
        render_path = _render_path(perception, args)
        if args.data_collection_exploration < 0:
            raise ValueError(f"--data-collection-exploration {args.data_collection_exploration} is negative")
        encoder = _encoder(args, stems["goal_rvt"]) if "goal_rvt" in methods else None
        run = {"eval_set_version": EVAL_SET_VERSION, "robot": args.robot, "rig": perception.rig, "hand_half_turn": half_turn,
               "pseudo_grouping": PSEUDO_GROUPING, "keypose_alternatives": alternatives, "mode_guidance": guidance,
               "noise_scale": noise_scale,
               "methods": {m: described.get(m, {}).get("weights_sha256") or ("dataset " + _data_digest(args.data)
                                                                          if m == "data_collection" else m) for m in methods}}
        if "data_collection" in methods:
            run["data_collection_exploration"] = args.data_collection_exploration
        check_run(args.out, run)
        gmm = None
        if "data_collection" in methods:
            gmm = data_collection_samplers(args.data, objects)
            unexplored = [o for o in objects if o.key not in gmm]
            if unexplored and args.data_collection_exploration > 0:
                print(f"Data Collection: exploring {len(unexplored)} object(s) the training dataset does not hold, "
                      f"{args.data_collection_exploration} trajectories each, into {args.out / EXPLORATION_DIR}")
                explored, labelling = explored_samplers(args.data, unexplored, args.out / EXPLORATION_DIR,
                                                        args.data_collection_exploration, render_path,
                                                        max(1, args.workers), not args.no_progress)
                gmm.update(explored)
                print("Data Collection: the training dataset's success label on them: "
                      + ", ".join(f"{split} accuracy {m['accuracy']:.1%}, balanced {m['balanced_accuracy']:.1%} "
                                  f"({m['n']} trajectories)" for split, m in labelling["per_split"].items()))
    except (ValueError, FileNotFoundError, RunMismatchError) as exc:
        print(f"actaim2 evaluate: {exc}", file=sys.stderr)
        return 2
    setup = WorkerSetup(args.robot, perception.rig, render_path, tuple(perception.center), float(perception.half_extent),
                        {m: str(stems[m]) for m in described}, str(encoder) if encoder else None, gmm,
                        hand_half_turn=half_turn, keypose_alternatives=alternatives, mode_guidance=guidance,
                        noise_scale=noise_scale)
    if args.grounding:
        return _grounding(args, setup, methods)
    clusters = {m: described[m]["clusters"] if m in described and m != "goal_rvt" else 0 for m in methods}
    skip = {"data_collection": {o.key for o in objects if o.key not in (gmm or {})}}
    if gmm is not None and skip["data_collection"]:
        print(f"Data Collection: {len(skip['data_collection'])} object(s) have no collected trajectories in {args.data}; "
              f"left out of its row", file=sys.stderr)
    tasks = plan_tasks({m: clusters[m] for m in methods}, objects, preset.counts, skip)
    reference: dict[str, dict] = {}
    if args.reproduce is not None:
        try:
            if args.reproduce_samples < 1:
                raise ValueError(f"--reproduce-samples {args.reproduce_samples} is not a count of samples")
            reference = reference_records(args.reproduce)
        except (ValueError, FileNotFoundError) as exc:
            print(f"actaim2 evaluate: --reproduce: {exc}", file=sys.stderr)
            return 2
        chosen = set(choose([t.key for t in tasks if t.key in reference], args.reproduce_samples))
        if not chosen:
            print(f"actaim2 evaluate: --reproduce: none of this command's samples are in {args.reproduce}",
                  file=sys.stderr)
            return 2
        tasks = [t for t in tasks if t.key in chosen]
    log = ResultLog(args.out)
    todo = [t for t in tasks if t.key not in log.done]
    print(f"{len(tasks)} samples ({preset.name}: {len(objects)} objects, rows {', '.join(methods)}); "
          f"{len(tasks) - len(todo)} already done; render path {render_path}")
    if lock is not None:  # before any sample: an interrupted --final run counts too
        append_ledger(args.ledger, lock, "evaluate", str(args.out), guarded, locked, len(todo))
        print(f"this --final run is line {len(read_ledger(args.ledger))} of {args.ledger}")
    started = time.perf_counter()
    errors = log.run(EvalWorker, setup, todo, args.workers, args.ray, not args.no_progress)
    seconds = time.perf_counter() - started
    header = _header(args, preset.name, described, render_path, len(objects), len(tasks), len(log.records), errors, seconds)
    records = [log.records[t.key] for t in tasks if t.key in log.records]
    text = report(records, methods, header)
    videos = preset.videos if args.videos is None else args.videos
    if (args.figures > 0 or videos > 0) and "actaim2" in methods:
        from actaim2.eval.figures import write_figures
        from actaim2.eval.video import video_table, write_videos

        worker = EvalWorker(setup)  # re-executes ActAIM2 samples for the pictures
        if args.figures > 0:
            paths = write_figures(worker, tasks, log.records, args.out / "figures", args.figures)
            text += "\n## Figures\n\n" + "\n".join(f"![{p.stem}](figures/{p.name})" for p in paths) + "\n"
        if videos > 0:
            text += video_table(write_videos(worker, tasks, log.records, args.out / "videos", videos), args.out)
    (args.out / "tables.md").write_text(text)
    if reference:
        agreed = agreement(reference, log.records, [t.key for t in tasks])
        (args.out / REPRODUCTION_FILE).write_text(json.dumps({"reference": str(args.reproduce), **agreed}, indent=2))
        print(f"reproduced {agreed['same']} of {agreed['samples']} outcomes of {args.reproduce} "
              f"({agreed['not_run']} not run); {args.out / REPRODUCTION_FILE}")
    print(f"{len(todo) - errors} samples run in {seconds:.0f} s ({errors} errors, retried by a rerun); tables: {args.out / 'tables.md'}")
    return 0 if errors == 0 else 1


def _grounding(args: argparse.Namespace, setup, methods: list[str]) -> int:
    """The grounding experiment: runs of (method, target, seed), resumable by run, then the reward plot."""
    import numpy as np

    from actaim2.eval.evalset import catalogue_objects
    from actaim2.eval.grounding import GROUNDING_METHODS, GroundingRun, reward_plot
    from actaim2.eval.results import ResultLog
    from actaim2.eval.worker import EvalWorker
    from actaim2.sim.objects.catalog import SPLITS

    category, _, instance = args.grounding.partition(":")
    split = next((name for name, members in SPLITS.items() if instance.isdigit() and int(instance) in members.get(category, ())), None)
    chosen = [m for m in GROUNDING_METHODS if m in methods]
    if split is None or not chosen:
        print(f"actaim2 evaluate: --grounding needs a catalogue CATEGORY:INSTANCE (got {args.grounding!r}) and a checkpoint "
              f"among --checkpoint, --cvae, --vqvae", file=sys.stderr)
        return 2
    obj = next(o for o in catalogue_objects((split,), 0, (category,)) if o.instance == int(instance))
    runs = [GroundingRun(m, obj, target, seed, args.grounding_iterations) for m in chosen for target in (1, -1)
            for seed in range(args.grounding_seeds)]
    log = ResultLog(args.out / "grounding")
    todo = [r for r in runs if r.key not in log.done]
    print(f"grounding on {obj.key}: {len(runs)} runs of {args.grounding_iterations} samples, {len(runs) - len(todo)} already done")
    errors = log.run(EvalWorker, setup, todo, args.workers, args.ray, not args.no_progress, unit="run")
    results = [log.records[r.key] for r in runs if r.key in log.records]
    if results:
        (args.out / "figures").mkdir(parents=True, exist_ok=True)
        reward_plot(results, args.out / "figures" / "grounding.png")
        lines = [f"# Interaction-mode grounding on {obj.key}", "", f"Command: `actaim2 evaluate {' '.join(sys.argv[2:])}`", "",
                 "| method | search | target | runs | mean reward, last 10 iterations |", "|---|---|---|---|---|"]
        for m in chosen:
            for target in (1, -1):
                rewards = [r["rewards"][-10:] for r in results if r["method"] == m and r["target"] == target]
                if rewards:
                    lines.append(f"| {m} | {'Thompson bandit over clusters' if m == 'actaim2' else 'CEM over the embedding'} | "
                                 f"{'open' if target > 0 else 'close'} | {len(rewards)} | {np.mean(rewards):.2f} |")
        lines += ["", "![grounding](figures/grounding.png)"]
        (args.out / "grounding.md").write_text("\n".join(lines) + "\n")
    print(f"grounding: {len(results)} runs in the results, {errors} errors; {args.out / 'grounding.md'}")
    return 0 if errors == 0 else 1


def _data_digest(data: Path | None) -> str:
    from actaim2.data.storage import dataset_digest

    return dataset_digest(data) if data is not None else "-"


def _header(args, preset: str, described: dict, render_path: str, n_objects: int, n_tasks: int, n_done: int,
            errors: int, seconds: float) -> list[str]:
    from actaim2.eval.evalset import EVAL_SET_VERSION
    from actaim2.eval.results import machine_description

    command = "actaim2 evaluate " + " ".join(shlex.quote(a) for a in sys.argv[2:]) if sys.argv[1:2] == ["evaluate"] \
        else "actaim2 evaluate (called from Python)"
    lines = ["# actaim2 evaluation", "", f"Command: `{command}`", "",
             f"- size: {preset}, {n_objects} objects, {n_tasks} samples planned, {n_done} in the results "
             f"({errors} errors this run), evaluation set version {EVAL_SET_VERSION}",
             f"- this run: {seconds:.0f} s on {args.workers} worker(s){' (Ray ' + args.ray + ')' if args.ray else ''}, "
             f"load average {os.getloadavg()[0]:.1f}, render path {render_path}, robot {args.robot}",
             f"- machine: {machine_description()}, {os.cpu_count()} cores"]
    for method, d in described.items():
        lines.append(f"- {method}: checkpoint `{d['path']}`, weights sha256 `{d['weights_sha256']}`, "
                     f"dataset {d['dataset_digest']}, views {d['perception_digest']}, predictor reads "
                     f"{'+'.join(d['predictor_inputs'])} of {d['predictor_view']} view(s)")
    if args.data is not None:
        lines.append(f"- dataset `{args.data}` digest {_data_digest(args.data)}")
    return lines
