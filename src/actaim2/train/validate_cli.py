"""`actaim2 validate`: curves and validation figures of a training run.

Examples:
    actaim2 validate runs/cpu --data data/v2                       # runs/cpu/policy on train_unseen_instance
    actaim2 validate runs/ring5 --data data/v2 --checkpoint actaim2_policy/checkpoints/actaim2_ring5   # no curves
    actaim2 validate runs/cpu --data data/v2 --split heldout_category
    actaim2 validate runs/pm --data data/pm --catalogue partnet            # runs/pm/policy on val

Writes into the run folder: ``curves.png`` (training and validation curves from
``history.jsonl``; a folder without it, e.g. for a shipped checkpoint, gets none), ``validation.json`` and ``validation.md`` (translation, rotation and gripper
errors of the predictor, whether its keyposes follow the outcome eps names (its own, drawn, or
another trajectory's), the selector's
reconstruction error and cluster usage on the visually-labelled successes of ``--split``; see
actaim2.train.validation).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

from actaim2.data.collect_cli import add_catalogue_arguments
from actaim2.data.splits import GENERATED, PARTNET, PARTNET_VAL, UNSEEN_INSTANCE
from actaim2.protocol.arguments import add_protocol_arguments, splits_files
from actaim2.train.train_cli import add_threads_argument

DEFAULT_SPLIT = {GENERATED.name: UNSEEN_INSTANCE, PARTNET.name: PARTNET_VAL}  # per catalogue


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run", type=Path, help="an `actaim2 train` run folder (history.jsonl, policy), or with "
                        "--checkpoint any folder to write the figures into (no curves without history.jsonl)")
    parser.add_argument("--data", type=Path, required=True, help="the dataset folder the run was trained on")
    parser.add_argument("--checkpoint", type=Path, help="policy checkpoint stem (default <run>/policy)")
    add_catalogue_arguments(parser)
    parser.add_argument("--split", help="split whose successes are measured (default: generated "
                                        "train_unseen_instance, partnet val; a test split only "
                                        "with --final under the protocol lock)")
    add_protocol_arguments(parser)
    parser.add_argument("--perception", default="ring5", help="perception configuration the checkpoint was trained with")
    parser.add_argument("--noise-scale", type=float, default=None, metavar="S",
                        help="spread of the selector's draws (ModeSelector.sample; default as policy_node's noise_scale, "
                             "1 = as trained, 0 = each cluster's noise-free eps)")
    add_threads_argument(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def main(args: argparse.Namespace) -> int:
    from actaim2.artifact import checkpoint
    from actaim2.artifact.device import choose_device
    from actaim2.artifact.serving import DEFAULT_SERVING, check_noise_scale
    from actaim2.data.splits import catalogue
    from actaim2.data.storage import DatasetReader, dataset_digest, object_of
    from actaim2.models.view_geometry import CubePlacement
    from actaim2.perception.config import load_perception_config
    from actaim2.protocol.lock import append_ledger, guarded_ids, protected
    from actaim2.protocol.lock import check_run as check_protocol
    from actaim2.train.curves import plot_curves, read_history
    from actaim2.train.data import ensure_cache, open_cache
    from actaim2.train.distributed import set_cpu_threads
    from actaim2.train.validation import (
        action_figures,
        drawn_following,
        markdown,
        mode_chain_figures,
        outcome_figures,
        predict_keyframes,
        selector_figures,
        swapped_following,
    )

    if args.threads < 0:
        print(f"actaim2 validate: --threads {args.threads} is negative")
        return 2
    noise_scale = DEFAULT_SERVING.noise_scale if args.noise_scale is None else args.noise_scale
    try:
        check_noise_scale(noise_scale, "--noise-scale")
    except ValueError as exc:
        print(f"actaim2 validate: {exc}")
        return 2
    set_cpu_threads(args.threads)
    stem = args.checkpoint or args.run / "policy"
    args.run.mkdir(parents=True, exist_ok=True)
    perception = load_perception_config(args.perception)
    device = choose_device("auto")
    try:
        policy = checkpoint.load_policy(stem, checkpoint.perception_record(perception), device)
    except checkpoint.CheckpointError as exc:
        print(f"actaim2 validate: {exc}")
        return 1
    if policy.selector is None or policy.predictor is None:
        print(f"actaim2 validate: {stem} must hold both a selector and a predictor")
        return 1
    split = args.split or DEFAULT_SPLIT[args.catalogue]
    digest = policy.meta.get("weights_sha256")
    try:
        catalogue(args.catalogue).check_splits((split,), "--split")
        reader = DatasetReader(args.data)
        measured = {(e["split"], e["object_id"] if e.get("instance", -1) < 0 else "")
                    for e in reader.entries if e["split"] == split}
        folders = [Path(folder) for folder, _ in reader.info.get("folders", [])]
        test_ids = guarded_ids(splits_files(args, folders))
        guarded = protected(sorted(measured | {(split, "")}), test_ids)
        lock = check_protocol("validate", guarded, args.final, args.lock, [str(digest)])
    except (ValueError, FileNotFoundError) as exc:
        print(f"actaim2 validate: {exc}")
        return 2
    if lock is not None:  # before any measurement: an interrupted --final run counts too
        trajectories = sum(e["split"] == split for e in reader.entries)
        append_ledger(args.ledger, lock, "validate", str(args.run), guarded, [str(digest)],
                      trajectories)
    # measuring, not training
    ensure_cache(args.data, perception, [split], not args.no_progress, allow_held_out=True)
    data = open_cache(args.data, perception, [split])
    if data.outcomes is None:
        print(f"actaim2 validate: {args.data} split {split} has trajectories without a DoF "
              "measurement (dof_change), so no outcome to follow: validate a simulated collection")
        return 1
    placement = CubePlacement.of(perception)
    predictions = predict_keyframes(policy.selector, policy.predictor, data, placement, device)
    actions = action_figures(predictions)
    selector = selector_figures(policy.selector, data, device)
    objects, outcomes = [object_of(t) for t in data.ids], data.outcomes.tolist()
    follow = outcome_figures(predictions, objects, outcomes)
    chain = mode_chain_figures(policy.selector, data, objects, outcomes, device, noise_scale=noise_scale)
    drawn = drawn_following(policy.selector, policy.predictor, data, placement, predictions, objects, outcomes, device,
                            noise_scale=noise_scale)
    swapped = swapped_following(policy.selector, policy.predictor, data, placement, predictions, objects, outcomes, device)
    report = {"checkpoint": str(stem), "weights_sha256": digest, "dataset": str(args.data),
              "dataset_digest": dataset_digest(args.data), "split": split,
              "noise_scale": noise_scale,
              "actions": {k: {p: dataclasses.asdict(f) for p, f in v.items()} for k, v in actions.items()}, "selector": selector,
              "outcome_following": {p: dataclasses.asdict(f) for p, f in follow.items()},
              "drawn_following": {p: dataclasses.asdict(f) for p, f in drawn.items()},
              "swapped_following": {p: dataclasses.asdict(f) for p, f in swapped.items()}, "mode_chain": dataclasses.asdict(chain)}
    (args.run / "validation.json").write_text(json.dumps(report, indent=2) + "\n")
    text = markdown(split, actions, selector, follow, chain, drawn, swapped, noise_scale)
    (args.run / "validation.md").write_text(text)
    print(text)
    written = [args.run / "validation.json", args.run / "validation.md"]
    if (args.run / "history.jsonl").exists():  # a training run: its curves too
        written.append(plot_curves(read_history(args.run), args.run / "curves.png",
                                   title=f"{args.run} (weights {str(digest)[:12]}), validation: 10% of train_seen"))
    print("wrote " + ", ".join(map(str, written)))
    return 0
