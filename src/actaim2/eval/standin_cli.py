"""`actaim2 eval-standin`: the three-drawer stand-in, before and after fine-tuning.

    actaim2 eval-standin --before runs/azure/policy --after runs/azure_ft/policy --out runs/standin
    actaim2 eval-standin --before runs/azure/policy --after runs/azure_ft/policy --out runs/standin-quick --quick
    actaim2 eval-standin --before runs/azure/policy --push-cluster 3 --pull-cluster 5 --out runs/standin-pre

The protocol is in :mod:`actaim2.eval.standin`. Push (pull) asks each checkpoint for the cluster of
the fine-tuned checkpoint's cluster table (its ``lineage.finetune``: the ``after`` table for it,
the ``before`` table, its parent's selector on the same demonstrations, for the parent), unless
``--push-cluster`` / ``--pull-cluster`` name one for both. The scene is the demonstrations':
the checkpoints' rig (``azure_kinect``) with its sensor model (range noise, invalid pixels,
extrinsic jitter), as ``sim_node`` simulates it; ``--domain-randomisation`` adds the lighting,
colour, placement and noise randomisation of a pretraining collection instead.
Interrupt it at any time: the same command resumes. Writes <out>/standin.md, <out>/standin.json
and the episodes' records, <out>/results.jsonl.
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--after", type=Path, help="the fine-tuned checkpoint (stem); its lineage names the push and pull clusters")
    parser.add_argument("--before", type=Path, help="the checkpoint it was fine-tuned from (stem)")
    parser.add_argument("--out", type=Path, required=True, help="results folder (created, or resumed if it exists)")
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--placements", type=int, default=10, help="held-out placements (x 3 initial states)")
    size.add_argument("--quick", action="store_true", help="1 placement")
    parser.add_argument("--push-cluster", type=int, help="the cluster asked for push, in both checkpoints")
    parser.add_argument("--pull-cluster", type=int, help="the cluster asked for pull, in both checkpoints")
    parser.add_argument("--modes-only", action="store_true",
                        help="ask only the push and pull clusters (6 episodes per placement and checkpoint instead of 3 x K): "
                             "no per-cluster table")
    parser.add_argument("--robot", default="kinova_j2s6s200", help="robot preset or YAML (the demonstrations')")
    parser.add_argument("--domain-randomisation", metavar="NAME_OR_YAML",
                        help="randomise every reset as a collection does ('default': the bundled domain_randomisation.yaml); "
                             "default: none, the rig's own sensor model as sim_node has it")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (0 = in this process)")
    parser.add_argument("--render-path", choices=["sapien", "raycast"], help="override the configuration's render path")
    parser.add_argument("--allow-raycast", action="store_true", help="without a Vulkan device, render by ray casting instead of refusing")
    parser.add_argument("--no-refine-extrinsic", action="store_true",
                        help="serve views through the rig's nominal extrinsic (by default each picture's is refined from "
                             "the robot in it before the self-filter, as bag2dataset refines the demonstrations')")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _conditions(args: argparse.Namespace) -> dict[str, Path]:
    conditions = {name: stem for name, stem in (("before", args.before), ("after", args.after)) if stem is not None}
    if not conditions:
        raise ValueError("give --after (the fine-tuned checkpoint), --before (its parent), or both")
    return conditions


def main(args: argparse.Namespace) -> int:
    from actaim2.artifact.checkpoint import paths
    from actaim2.eval.checkpoints import describe, perception_of
    from actaim2.eval.evalset import EVAL_SET_VERSION
    from actaim2.eval.evaluate_cli import _render_path
    from actaim2.eval.results import ResultLog, RunMismatchError, check_run
    from actaim2.eval.standin import (
        MODES,
        SHELF,
        STATE_NAMES,
        StandinWorker,
        mode_clusters,
        placement_seeds,
        plan_episodes,
        summarise,
        summary_json,
        tables,
    )
    from actaim2.eval.worker import WorkerSetup
    from actaim2.sim.randomisation import load_randomisation

    placements = 1 if args.quick else args.placements
    overrides = {"push": args.push_cluster, "pull": args.pull_cluster}
    try:
        if placements < 1:
            raise ValueError(f"--placements must be at least 1, got {placements}")
        stems = _conditions(args)
        described = {c: describe(s) for c, s in stems.items()}
        for c, d in described.items():
            if d["clusters"] < 1:
                raise ValueError(f"{c}: checkpoint {stems[c]} has no discrete clusters ({d['selector']} selector): "
                                 f"the stand-in asks for clusters")
        finetune = json.loads(paths(args.after)[1].read_text()).get("lineage", {}).get("finetune") if args.after else None
        asked = {c: mode_clusters(c, finetune, d["weights_sha256"], d["clusters"], overrides) for c, d in described.items()}
        configs = {c: perception_of(s) for c, s in stems.items()}
        perception = next(iter(configs.values()))
        for c, config in configs.items():
            if (config.rig, config.center, config.half_extent) != (perception.rig, perception.center, perception.half_extent):
                raise ValueError(f"the {c} checkpoint was trained on rig {config.rig} (cube {config.center}, {config.half_extent}), "
                                 f"the {next(iter(configs))} one on {perception.rig} ({perception.center}, {perception.half_extent})")
        render_path = _render_path(perception, args)
        randomisation = load_randomisation(args.domain_randomisation).to_dict() if args.domain_randomisation else None
        check_run(args.out, {"eval_set_version": EVAL_SET_VERSION, "robot": args.robot, "rig": perception.rig,
                             "refine_extrinsic": not args.no_refine_extrinsic,
                             "methods": {c: {"weights_sha256": d["weights_sha256"], "domain_randomisation": randomisation}
                                         for c, d in described.items()}})
    except (ValueError, FileNotFoundError, RunMismatchError) as exc:
        print(f"actaim2 eval-standin: {exc}", file=sys.stderr)
        return 2
    setup = WorkerSetup(args.robot, perception.rig, render_path, tuple(perception.center), float(perception.half_extent),
                        {c: str(s) for c, s in stems.items()}, randomisation=randomisation,
                        refine_extrinsic=not args.no_refine_extrinsic)
    k = {c: d["clusters"] for c, d in described.items()}
    clusters = {c: sorted(set(asked[c][0].values())) if args.modes_only else list(range(k[c])) for c in stems}
    episodes = plan_episodes(clusters, k, placements)
    log = ResultLog(args.out)
    todo = [e for e in episodes if e.key not in log.done]
    print(f"{len(episodes)} episodes ({placements} placement(s) x {len(STATE_NAMES)} initial states x clusters "
          f"{', '.join(f'{c}: {len(v)}' for c, v in clusters.items())}); {len(episodes) - len(todo)} already done; "
          f"render path {render_path}")
    started = time.perf_counter()
    errors = log.run(StandinWorker, setup, todo, args.workers, show_progress=not args.no_progress, unit="episode")
    seconds = time.perf_counter() - started
    records = [log.records[e.key] for e in episodes if e.key in log.records]
    summaries = {c: summarise([r for r in records if r["method"] == c], asked[c][0],
                              k[c] if not args.modes_only else 0) for c in stems}
    command = "actaim2 eval-standin " + " ".join(shlex.quote(a) for a in sys.argv[2:]) if sys.argv[1:2] == ["eval-standin"] \
        else "actaim2 eval-standin (called from Python)"
    ran = [log.records[e.key] for e in todo if e.key in log.records]
    machine = {"episodes_run": len(ran), "errors": errors, "wall_seconds": round(seconds, 1), "workers": args.workers,
               "load_average": round(os.getloadavg()[0], 2),
               "episode_seconds": round(sum(r["seconds"] for r in ran) / len(ran), 2) if ran else None,
               "episode_cpu_seconds": round(sum(r["cpu_seconds"] for r in ran) / len(ran), 2) if ran else None}
    report = {"command": command,
              "protocol": {"object": SHELF.key, "placements": placements, "reset_seeds": placement_seeds(placements),
                           "initial_states": list(STATE_NAMES), "modes": MODES, "robot": args.robot, "rig": perception.rig,
                           "render_path": render_path, "domain_randomisation": randomisation,
                           "refine_extrinsic": setup.refine_extrinsic,
                           "velocity_scaling": setup.velocity_scaling, "episodes": len(episodes), "in_results": len(records)},
              "conditions": {c: {"checkpoint": described[c], "mode_clusters": asked[c][0], "mode_clusters_from": asked[c][1],
                                 "asked_clusters": clusters[c], **summary_json(summaries[c])} for c in stems},
              "this_run": machine}
    (args.out / "standin.json").write_text(json.dumps(report, indent=2))
    header = ["# Three-drawer stand-in", "", f"Command: `{command}`", "",
              f"- {SHELF.key}, {placements} held-out placement(s) (reset seeds {report['protocol']['reset_seeds']}) x "
              f"{len(STATE_NAMES)} initial states (one drawer half-open, the others shut); robot {args.robot}, rig "
              f"{perception.rig}, render path {render_path}, domain randomisation {args.domain_randomisation or 'none'}, "
              f"velocity scaling {setup.velocity_scaling}",
              *(f"- {c}: checkpoint `{described[c]['path']}`, weights sha256 `{described[c]['weights_sha256']}`, "
                f"{k[c]} clusters; push -> c{asked[c][0]['push']}, pull -> c{asked[c][0]['pull']} ({asked[c][1]})" for c in stems),
              f"- {len(records)} of {len(episodes)} episodes in the results; this run: " +
              (f"{len(ran)} episodes in {seconds:.0f} s on {args.workers} worker(s), {machine['episode_seconds']} s per episode "
               f"({machine['episode_cpu_seconds']} s CPU; a worker's first episode builds the shelf), "
               f"load average {machine['load_average']}" if ran else "nothing left to run"), ""]
    (args.out / "standin.md").write_text("\n".join(header + tables(summaries)) + "\n")
    print(f"{len(ran)} episodes run in {seconds:.0f} s ({errors} errors, retried by a rerun); {args.out / 'standin.md'}")
    return 0 if errors == 0 else 1
