"""`actaim2 finetune CHECKPOINT DATASET`: fine-tune a policy's selector and predictor on demonstrations.

Examples:
    actaim2 finetune runs/azure/policy data/teleop --out runs/azure_ft
    actaim2 finetune runs/azure/policy data/teleop --out runs/azure_ft --pretraining-data data/sim --epochs 40

DATASET is a converted set of demonstrations (``actaim2 bag2dataset``); the checkpoint's own
perception configuration renders its views. Prints the losses on the training and held-out
demonstrations before and after, the cluster each labelled demonstration falls into, and (labels used, the
default) each mode label's cluster with the held-out demonstrations' mode accuracy. The new
checkpoint is ``<out>/policy`` (its JSON's ``lineage.finetune`` names the parent, the dataset and
this command); ``<out>/finetune.json`` holds the same report.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("checkpoint", type=Path, help="parent checkpoint stem (<stem>.json + <stem>.safetensors)")
    parser.add_argument("dataset", type=Path, help="demonstrations (actaim2 bag2dataset)")
    parser.add_argument("--out", type=Path, required=True, help="run folder: policy checkpoint, history.jsonl, finetune.json")
    parser.add_argument("--phases", nargs="+", choices=["selector", "predictor", "joint"], default=["joint"],
                        help="training-loop phases to run (default: the joint phase, both models, sg[eps])")
    parser.add_argument("--epochs", type=float, default=20.0, help="epochs per phase")
    parser.add_argument("--batch-size", type=int, default=8)
    parser.add_argument("--lr", type=float, default=1e-4, help="peak learning rate (warm-up and decay as the parent's)")
    parser.add_argument("--heldout", type=float, default=0.2, help="fraction of each mode label's demonstrations held out")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--device", choices=["auto", "cpu", "cuda"], default="auto")
    parser.add_argument("--pretraining-data", type=Path,
                        help="the parent's training dataset: checks that the demonstrations' encoder E is its encoder")
    parser.add_argument("--no-mode-labels", action="store_true",
                        help="ignore the demonstrations' mode labels: every cluster inferred (by default each label "
                             "gets a cluster of its own)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def _losses(block: dict) -> str:
    parts = []
    for side in ("train", "val"):
        values = block.get(side)
        parts.append(f"{side} {values['loss']:.4f}" if values else f"{side} -")
    return ", ".join(parts)


def command(args: argparse.Namespace) -> list[str]:
    """The command that repeats this run, every option spelled out (defaults included): the lineage's."""
    line = ["actaim2", "finetune", str(args.checkpoint), str(args.dataset), "--out", str(args.out), "--phases", *args.phases,
            "--epochs", str(args.epochs), "--batch-size", str(args.batch_size), "--lr", str(args.lr),
            "--heldout", str(args.heldout), "--seed", str(args.seed), "--device", args.device]
    return line + (["--pretraining-data", str(args.pretraining_data)] if args.pretraining_data else []) \
        + (["--no-mode-labels"] if args.no_mode_labels else [])


def main(args: argparse.Namespace) -> int:
    from actaim2.artifact.checkpoint import CheckpointError
    from actaim2.finetune.clusters import format_table
    from actaim2.finetune.finetune import FinetuneConfig, finetune

    config = FinetuneConfig(phases=tuple(args.phases), epochs=args.epochs, batch_size=args.batch_size, lr=args.lr,
                            heldout_fraction=args.heldout, seed=args.seed, device=args.device,
                            mode_labels=not args.no_mode_labels)
    try:
        report = finetune(args.checkpoint, args.dataset, args.out, config, command(args),
                          args.pretraining_data, show_progress=not args.no_progress)
    except (ValueError, FileNotFoundError, CheckpointError) as exc:  # FinetuneError and perception mismatches are ValueErrors
        print(f"actaim2 finetune: {exc}")
        return 2
    print(json.dumps({"parent": report["parent"], "dataset": report["dataset"], "encoder": report["encoder"],
                      "heldout": len(report["heldout"]), "phases": report["phases"]}, indent=2))
    for phase in config.phases:
        print(f"{phase} loss before: {_losses(report['before'][phase])}; after: {_losses(report['after'][phase])}")
    print("\nclusters of the labelled demonstrations, before fine-tuning:\n" + format_table(report["before"]["clusters"]))
    print("\nafter fine-tuning:\n" + format_table(report["after"]["clusters"]))
    modes = report["mode_labels"]
    print(f"\nmode labels: {modes['note']}")
    if modes["label_cluster"]:
        print("label -> cluster: " + ", ".join(f"{label} c{c}" for label, c in sorted(modes["label_cluster"].items())))
        for side, accuracy in modes["heldout_accuracy"].items():
            per_label = ", ".join(f"{label} {v['correct']}/{v['demonstrations']}" for label, v in accuracy["by_label"].items())
            print(f"held-out mode accuracy {side}: {accuracy['correct']}/{accuracy['demonstrations']} ({per_label})")
    print(f"\nwrote {report['checkpoint']}.json / .safetensors")
    return 0
