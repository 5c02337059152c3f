"""`actaim2 bag2dataset`: recorded teleop bags -> a training dataset (the format collection writes).

Examples:
    actaim2 bag2dataset bags/teleop/episode_* --out data/teleop --encoder data/sim/encoder.pt
    actaim2 bag2dataset my_bag --out data/real --robot kinova_j2s6s200 --perception azure_kinect
    actaim2 bag2dataset bags/teleop/episode_* --out data/teleop --encoder data/azure/encoder.pt --checkpoint runs/azure/policy

``--encoder`` is the encoder E of the pretraining data (``<dataset>/encoder.pt``): the task
embeddings of the demonstrations must live in the space the pretrained selector learned;
``--checkpoint`` (the policy to fine-tune) refuses another E, naming both digests. A bag
or an episode that cannot be converted is reported and skipped; the command fails only when
nothing could be converted. What happened to each bag is in ``<out>/bag2dataset.json``.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bags", nargs="+", type=Path, help="rosbag2 folders (or .mcap/.db3 files), one or more episodes each")
    parser.add_argument("--out", type=Path, required=True, help="dataset folder to create")
    parser.add_argument("--encoder", type=Path,
                        help="the encoder E of the pretraining data (default: the one beside --checkpoint, <stem>.encoder.pt)")
    parser.add_argument("--perception", default="azure_kinect",
                        help="perception configuration (rig name or YAML) the policy is served with: its rig names the cloud topics")
    parser.add_argument("--robot", default="kinova_j2s6s200", help="the robot in the bags (preset or YAML): its self-filter hides it")
    parser.add_argument("--checkpoint", type=Path,
                        help="the policy to fine-tune (stem): refuse --encoder unless it is the E that policy was trained with")
    parser.add_argument("--no-refine-extrinsic", action="store_true",
                        help="keep /tf_static's camera extrinsics as they are (by default each episode's is refined "
                             "by registering the robot's own surface to its clouds)")


def main(args: argparse.Namespace) -> int:
    from actaim2.artifact.checkpoint import CheckpointError, encoder_path
    from actaim2.finetune.bag2dataset import bags_to_dataset
    from actaim2.perception.config import load_perception_config
    from actaim2.perception.extrinsic_refinement import RefinementLimits

    encoder = args.encoder
    if encoder is None and args.checkpoint is None:
        print("actaim2 bag2dataset: give --encoder (the pretraining data's encoder.pt) or --checkpoint (its <stem>.encoder.pt is used)")
        return 2
    if encoder is None:
        encoder = encoder_path(args.checkpoint)
        if not encoder.is_file():
            print(f"actaim2 bag2dataset: {args.checkpoint} has no encoder E beside it ({encoder}; checkpoints trained "
                  f"before encoders were shipped): give --encoder, the encoder.pt of the data it was trained on")
            return 2
    try:
        config = load_perception_config(args.perception)
        refinement = None if args.no_refine_extrinsic else RefinementLimits()
        summary = bags_to_dataset(args.bags, args.out, config, args.robot, encoder, checkpoint=args.checkpoint,
                                  refinement=refinement)
    except (FileNotFoundError, FileExistsError, ValueError, CheckpointError) as exc:
        print(f"actaim2 bag2dataset: {exc}")
        return 2
    fits = summary["intrinsics_residual_px"]
    print(json.dumps({k: summary[k] for k in ("trajectories", "bags_converted", "bags_with_problems", "mode_labels")}))
    if fits["max"] is not None:
        print(f"intrinsics fitted to every cloud: reprojection residual rms <= {fits['rms_max']:.4f} px, max {fits['max']:.4f} px")
    refined = summary["extrinsics_refined"]
    if refinement is not None and refined["cameras"]:
        print(f"extrinsics refined from the robot: {refined['refined']} of {refined['cameras']} (episode, camera), "
              f"largest correction {refined['largest_correction_mm']:.1f} mm / {refined['largest_correction_deg']:.2f} deg")
    print(f"wrote {args.out} (report: {args.out / 'bag2dataset.json'})")
    return 0 if summary["trajectories"] else 1
