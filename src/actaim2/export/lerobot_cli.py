"""`actaim2 export-lerobot DATASET --out DIR`: a stored dataset as a LeRobot dataset (format v2.1).

Examples:
    actaim2 export-lerobot data/teleop --out exports/teleop_lerobot
    actaim2 export-lerobot data/sim --out exports/sim_lerobot --successful-only

One episode per trajectory, one frame per keyframe, action = keypose (x y z, qx qy qz qw, gripper
closed), task = the mode label. The format and why it is written by this project rather than by
the ``lerobot`` package: ``actaim2.export.lerobot_v21``.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", type=Path, help="actaim2 dataset folder (collect or bag2dataset)")
    parser.add_argument("--out", type=Path, required=True, help="LeRobot dataset folder to create")
    parser.add_argument("--successful-only", action="store_true", help="only trajectories labelled successful")


def main(args: argparse.Namespace) -> int:
    from actaim2.export.lerobot_v21 import export_lerobot, read_lerobot

    try:
        info = export_lerobot(args.dataset, args.out, args.successful_only)
        read_lerobot(args.out)  # what was written reads back
    except (FileNotFoundError, FileExistsError, ValueError) as exc:
        print(f"actaim2 export-lerobot: {exc}")
        return 2
    print(f"wrote {args.out}: LeRobot {info['codebase_version']}, {info['total_episodes']} episodes, "
          f"{info['total_frames']} frames, {info['total_tasks']} tasks")
    return 0
