"""`actaim2` command line: one sub-command per job, each implemented in its own module.

A sub-command module exposes ``add_arguments(parser)`` and ``main(args) -> int`` and keeps
its heavy imports (SAPIEN, torch, Open3D) inside ``main`` so that building the parser stays
cheap: `actaim2 bench control` does not pay for SAPIEN.
"""
from __future__ import annotations

import argparse
import importlib
import sys

# command path -> (module, one-line help)
COMMANDS: dict[tuple[str, ...], tuple[str, str]] = {
    ("bench", "sim"): ("actaim2.bench.sim", "physics steps/s, render ms per camera, ring5 observation"),
    ("bench", "perception"): ("actaim2.bench.perception", "clouds-in to views-out latency, in-process and through the node"),
    ("bench", "bags"): ("actaim2.bench.bags", "bag_recorder MB/s, CPU and loss under a ring5 replay; bag_player timing error"),
    ("bench", "control"): ("actaim2.bench.control", "IK success and latency, Ruckig time, straight-line deviation"),
    ("bench", "models"): ("actaim2.bench.models_cli", "selector sample and predictor latency, training step, parameters"),
    ("bench", "throughput"): ("actaim2.bench.throughput",
                              "where evaluation samples' and collection trajectories' time goes"),
    ("bench", "standin-self-filter"): ("actaim2.bench.standin_self_filter",
                                       "arm left in the stand-in's O_init / O_final by the self-filter, nominal vs refined extrinsic"),
    ("bench", "services"): ("actaim2.bench.services", "/sample_mode and /predict_keypose round trips, policy_node RSS, episode wall time"),
    ("expert",): ("actaim2.rollout.expert_eval", "scripted expert success per category (proves the objects are manipulable)"),
    ("render",): ("actaim2.perception.render_cli", "render a bag or saved cloud into orthographic PNG views"),
    ("view",): ("actaim2.viz.view_cli", "a dataset, evaluation run or bags in the Rerun web viewer (offline, 127.0.0.1)"),
    ("collect",): ("actaim2.data.collect_cli", "self-supervised data collection in simulation"),
    ("prepare-objects",): ("actaim2.sim.objects.prepare_cli", "convex decomposition of real object folders into the hull cache"),
    ("stats",): ("actaim2.data.stats_cli", "statistics of a collected dataset"),
    ("train",): ("actaim2.train.train_cli", "train the policy: mode selector, action predictor, joint phase"),
    ("validate",): ("actaim2.train.validate_cli", "curves and validation figures of a training run (errors in mm and deg, cluster usage)"),
    ("evaluate",): ("actaim2.eval.evaluate_cli", "SSR and Mode SSR tables of the policy and the baselines in simulation"),
    ("protocol",): ("actaim2.eval.protocol_cli", "write results/protocol.lock; count the ledger"),
    ("eval-compare",): ("actaim2.eval.compare_cli", "two evaluation runs of the same samples, paired: SSRs, discordant samples, exact McNemar p"),
    ("eval-standin",): ("actaim2.eval.standin_cli", "the three-drawer stand-in: push / pull success before and after fine-tuning, per cluster"),
    ("parity",): ("actaim2.eval.parity_cli", "the ROS loop against the library evaluation on 20 fixed (object, seed, cluster) tuples"),
    ("bag-reindex",): ("actaim2.bags.reindex",
                       "finish the files of a bag whose recorder died, rebuild its metadata.yaml"),
    ("bag2dataset",): ("actaim2.finetune.bag2dataset_cli", "recorded teleop bags -> a training dataset (keyframes, views, embeddings, labels)"),
    ("finetune",): ("actaim2.finetune.finetune_cli", "fine-tune a checkpoint's selector and predictor on demonstrations"),
    ("export-lerobot",): ("actaim2.export.lerobot_cli", "a stored dataset or teleop bags as a LeRobot dataset (format v2.1 or v3.0)"),
    ("report",): ("actaim2.report.report_cli", "regenerate README.md's and docs/' tables from the records in results/"),
    ("launch",): ("actaim2.launch.cli", "start a node graph (sim_panda_ring5, sim_kinova_azure, real_kinova_azure) as processes"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="actaim2", description=__doc__.splitlines()[0])
    groups: dict[tuple[str, ...], argparse._SubParsersAction] = {(): parser.add_subparsers(dest="cmd0", required=True)}
    for path, (module, help_text) in sorted(COMMANDS.items()):
        for depth in range(1, len(path)):
            prefix = path[:depth]
            if prefix not in groups:
                sub = groups[prefix[:-1]].add_parser(prefix[-1], help=f"{prefix[-1]} commands")
                groups[prefix] = sub.add_subparsers(dest=f"cmd{depth}", required=True)
        leaf = groups[path[:-1]].add_parser(path[-1], help=help_text)
        leaf.set_defaults(_module=module)
        try:
            importlib.import_module(module).add_arguments(leaf)
        except ModuleNotFoundError as exc:  # a command whose module is not installed yet
            leaf.set_defaults(_missing=str(exc))
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if getattr(args, "_missing", None):
        print(f"actaim2: this command is not available: {args._missing}", file=sys.stderr)
        return 2
    return int(importlib.import_module(args._module).main(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
