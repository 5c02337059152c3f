"""`actaim2 export-lerobot INPUT --out DIR`: a stored dataset, or recorded teleop bags, as a
LeRobot dataset (format v2.1 or v3.0).

Examples:
    actaim2 export-lerobot data/teleop --out exports/teleop_lerobot              # v2.1
    actaim2 export-lerobot data/teleop --out exports/teleop_v3 --format v3
    actaim2 export-lerobot data/sim --out exports/sim_lerobot --successful-only
    actaim2 export-lerobot runs/teleop/episode_* --from-bags --checkpoint runs/azure/policy \\
        --out exports/teleop_v3 --format v3

One episode per trajectory, one frame per keyframe, action = keypose (x y z, qx qy qz qw, gripper
closed), task = the mode label. ``--from-bags`` converts the bags as ``actaim2 bag2dataset``
does (same options) into a dataset beside the export (``<out>.dataset``), then exports it. The
formats and why they are written by this project rather than by the ``lerobot`` package:
``actaim2.export.lerobot_v21`` and ``actaim2.export.lerobot_v3``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

FORMATS = ("v2.1", "v3")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("inputs", nargs="+", type=Path,
                        help="an actaim2 dataset folder (collect or bag2dataset); with "
                             "--from-bags: rosbag2 folders or files")
    parser.add_argument("--out", type=Path, required=True, help="LeRobot dataset folder to create")
    parser.add_argument("--format", choices=FORMATS, default="v2.1", help="LeRobot format version")
    parser.add_argument("--successful-only", action="store_true",
                        help="only trajectories labelled successful")
    parser.add_argument("--from-bags", action="store_true",
                        help="the inputs are teleop bags: convert them first "
                             "(bag2dataset's options)")
    bags = parser.add_argument_group("with --from-bags (as actaim2 bag2dataset)")
    bags.add_argument("--encoder", type=Path, help="the encoder E of the pretraining data")
    bags.add_argument("--checkpoint", type=Path, help="the policy to fine-tune (its E is used)")
    bags.add_argument("--perception", default="azure_kinect", help="perception configuration")
    bags.add_argument("--robot", default="kinova_j2s6s200", help="the robot in the bags")
    bags.add_argument("--no-refine-extrinsic", action="store_true", help="keep /tf_static's camera extrinsics as they are")


def main(args: argparse.Namespace) -> int:
    from actaim2.export.lerobot_v3 import export_lerobot_v3, read_lerobot_v3
    from actaim2.export.lerobot_v21 import export_lerobot, read_lerobot

    if args.from_bags:
        from actaim2.finetune import bag2dataset_cli

        dataset = args.out.with_name(args.out.name + ".dataset")
        converted = argparse.Namespace(bags=args.inputs, out=dataset, encoder=args.encoder,
                                       checkpoint=args.checkpoint, perception=args.perception,
                                       robot=args.robot, no_refine_extrinsic=args.no_refine_extrinsic)
        if bag2dataset_cli.main(converted) != 0:
            print("actaim2 export-lerobot: the bags could not be converted (above)")
            return 2
    elif len(args.inputs) != 1:
        print("actaim2 export-lerobot: give one dataset folder (or --from-bags with bags)")
        return 2
    else:
        dataset = args.inputs[0]
    export, read = (export_lerobot_v3, read_lerobot_v3) if args.format == "v3" \
        else (export_lerobot, read_lerobot)
    try:
        info = export(dataset, args.out, args.successful_only)
        read(args.out)  # what was written reads back
    except (FileNotFoundError, FileExistsError, ValueError) as exc:
        print(f"actaim2 export-lerobot: {exc}")
        return 2
    print(f"wrote {args.out}: LeRobot {info['codebase_version']}, "
          f"{info['total_episodes']} episodes, "
          f"{info['total_frames']} frames, {info['total_tasks']} tasks")
    return 0
