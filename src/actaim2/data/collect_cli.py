"""`actaim2 collect`: self-supervised data collection in simulation (random, grasp, GMM-adaptive).

Examples:
    actaim2 collect --out data/ds --random 50 --grasp 50 --gmm 50            # the paper's mix, all splits
    actaim2 collect --out data/small --instances-per-category 1 --random 10 --grasp 10 --gmm 5
    actaim2 collect --out data/ds --vgg19-weights vgg19-dcbb9e9d.pth         # E = a user's VGG-19
    actaim2 collect --out data/pm --objects ~/partnet-mobility --object-splits splits.yaml   # real folders
    actaim2 collect --out data/pm --catalogue partnet --partnet-root ~/pm        # its train split
    actaim2 collect --out data/pm --catalogue partnet --splits train,val --object table:0
    actaim2 collect --out data/ds --ray auto --workers 32                        # on a Ray cluster
    actaim2 collect --out data/ds --actions-per-placement 4                      # 4 trajectories per reset
    actaim2 collect --out data/ds --splits train_seen,train_extra                # twice the training objects
    actaim2 collect --out data/azure --robot kinova_j2s6s200 --perception azure_kinect --domain-randomisation default

Interrupt it at any time; the same command resumes where it stopped.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from actaim2.data.real_objects import FolderObject


def add_catalogue_arguments(parser: argparse.ArgumentParser) -> None:
    """``--catalogue`` and ``--partnet-root``, shared by collect, train, evaluate and validate."""
    parser.add_argument("--catalogue", choices=["generated", "partnet"], default="generated",
                        help="where objects and split names come from: the generated catalogue "
                             "(train_seen, train_unseen_instance, heldout_category, train_extra) "
                             "or "
                             "real PartNet-Mobility folders split by the splits.yaml of "
                             "--partnet-root (train, val, test_unseen_instance, "
                             "test_unseen_category, extra; actaim2.data.real_objects)")
    parser.add_argument("--partnet-root", type=Path,
                        help="the partnet catalogue's folder (object folders + splits.yaml); "
                             "default $ACTAIM2_PARTNET")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, required=True, help="dataset folder (created, or resumed if it exists)")
    add_catalogue_arguments(parser)
    parser.add_argument("--splits", help="the catalogue's splits to collect on (comma separated; "
                                         "default: generated train_seen,train_unseen_instance,"
                                         "heldout_category; partnet train)")
    parser.add_argument("--categories", default="", help="only these categories (comma separated; default all in the splits)")
    parser.add_argument("--instances-per-category", type=int, default=0, help="only the first N instances of each category per split (0 = all)")
    parser.add_argument("--object", action="append", default=[], metavar="CATEGORY:INSTANCE",
                        help="collect on exactly these generated objects (repeatable; overrides "
                             "--splits/--categories of the generated catalogue; with --catalogue "
                             "partnet they are added to its objects)")
    parser.add_argument("--random", type=int, default=50, help="random-sampling trajectories per object")
    parser.add_argument("--grasp", type=int, default=50, help="heuristic-grasp trajectories per object")
    parser.add_argument("--gmm", type=int, default=50, help="GMM-adaptive trajectories per object")
    parser.add_argument("--other-splits-share", type=float, default=1.0,
                        help="objects outside the training splits (train_seen, train_extra) get this share of each count, "
                             "rounded up (e.g. 0.4: 50 -> 20)")
    parser.add_argument("--actions-per-placement", type=int, default=1, metavar="N",
                        help="trajectories of one sampler sharing a reset (placement, randomisation draw), so one O_init "
                             "comes with several actions and outcomes (default 1: one reset each)")
    parser.add_argument("--rounds", type=int, default=1, help="GMM refits while collecting the adaptive trajectories")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (0 = in this process); Ray actors with --ray")
    parser.add_argument("--ray", metavar="ADDRESS", help="run the trajectories on Ray actors (actaim2.parallel, as actaim2 evaluate "
                                                         "does): auto, ray://host:port, or local (a private instance on 127.0.0.1)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--robot", default="panda", help="robot preset or YAML (actaim2.robots)")
    parser.add_argument("--perception", default="ring5",
                        help="perception configuration: rig name (ring5, azure_kinect) or YAML; fixes the cameras, cube and render path")
    parser.add_argument("--render-path", choices=["sapien", "raycast"],
                        help="override the configuration's render path (sapien); raycast = collect ray-cast pictures on purpose")
    parser.add_argument("--allow-raycast", action="store_true",
                        help="without a Vulkan device, collect ray-cast pictures instead of refusing (logged, recorded in dataset.json)")
    parser.add_argument("--encoder", type=Path, help="a saved encoder E (ImageEncoder.save); default: train one on the data")
    parser.add_argument("--vgg19-weights", type=Path, help="torchvision VGG-19 state_dict file: use VGG-19 as E")
    parser.add_argument("--encoder-steps", type=int, default=800, help="training steps of the default encoder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.add_argument("--objects", type=Path, help="real PartNet-Mobility object folders (a folder of them, or one) instead of "
                                                     "the catalogue (--object adds catalogue objects); hulls prepared first")
    parser.add_argument("--object-splits", type=Path,
                        help="YAML 'folder name: split' (either catalogue's split names) for "
                             "--objects; other folders split by category, or refused under "
                             "--catalogue partnet (default there: its splits.yaml)")
    parser.add_argument("--hull-cache", type=Path, help="convex decompositions of --objects (default ~/.cache/actaim2/hulls)")
    parser.add_argument("--domain-randomisation", metavar="YAML|default",
                        help="randomise lighting, colours, placement, depth noise and extrinsics per reset "
                             "(actaim2.sim.randomisation; 'default': its bundled domain_randomisation.yaml)")


def _objects(args: argparse.Namespace) -> list[tuple[str, int]]:
    """The generated catalogue's objects: ``--object``, else its ``--splits`` (none under
    partnet)."""
    from actaim2.data.splits import GENERATED
    from actaim2.sim.objects.catalog import split_instances

    objects = []
    for text in args.object:
        category, _, instance = text.partition(":")
        if not instance.isdigit():
            raise ValueError(f"--object takes CATEGORY:INSTANCE, got {text!r}")
        objects.append((category, int(instance)))
    if objects or args.objects is not None or args.catalogue != GENERATED.name:
        return objects
    categories = {c for c in args.categories.split(",") if c}
    for split in _splits(args):
        chosen: dict[str, list[int]] = {}
        for category, instance in split_instances(split):
            if not categories or category in categories:
                chosen.setdefault(category, []).append(instance)
        for category, instances in chosen.items():
            keep = instances[: args.instances_per_category] if args.instances_per_category > 0 else instances
            objects += [(category, i) for i in keep]
    return objects


def _splits(args: argparse.Namespace) -> tuple[str, ...]:
    """``--splits`` (or the catalogue's default), each checked to be a split of the catalogue."""
    from actaim2.data.splits import catalogue

    chosen = catalogue(args.catalogue)
    if args.splits is None:
        return chosen.default_collect
    names = tuple(s for s in args.splits.split(",") if s)
    return chosen.check_splits(names, "--splits")


def _folders(args: argparse.Namespace) -> list[FolderObject]:
    """Real object folders: ``--objects`` (split by ``--object-splits``, or under partnet by its
    splits file), else the partnet catalogue's ``--splits``."""
    from actaim2.data.real_objects import (
        catalogue_folders,
        folder_objects,
        partnet_root,
        partnet_splits,
        read_object_splits,
    )

    partnet = args.catalogue == "partnet"
    if args.objects is not None:
        if args.object_splits is not None:
            splits = read_object_splits(args.object_splits)
        else:
            splits = partnet_splits(partnet_root(args.partnet_root)) if partnet else None
        return folder_objects(args.objects, splits, listed_only=partnet)
    if not partnet:
        return []
    categories = tuple(c for c in args.categories.split(",") if c)
    return catalogue_folders(partnet_root(args.partnet_root), _splits(args), categories,
                             args.instances_per_category)


def main(args: argparse.Namespace) -> int:
    from actaim2.data.collect import CollectConfig, collect
    from actaim2.data.encoder import ImageEncoder
    from actaim2.data.splits import split_of
    from actaim2.parallel import ray_available
    from actaim2.sim.randomisation import load_randomisation

    try:
        randomisation = load_randomisation(args.domain_randomisation) if args.domain_randomisation else None
        objects = _objects(args)
        for category, instance in objects:
            split_of(category, instance)  # only catalogued objects: their split must be known
        folders = _folders(args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"actaim2 collect: {exc}", file=sys.stderr)
        return 2
    if not objects and not folders:
        print("actaim2 collect: no object selected", file=sys.stderr)
        return 2
    if (min(args.random, args.grasp, args.gmm) < 0 or args.workers < 0 or args.rounds < 1 or args.actions_per_placement < 1
            or not 0 < args.other_splits_share <= 1):
        print("actaim2 collect: counts and --workers must be >= 0, --rounds and --actions-per-placement >= 1, "
              "--other-splits-share in (0, 1]", file=sys.stderr)
        return 2
    ray_problem = ray_available() if args.ray else None
    if ray_problem:
        print(f"actaim2 collect: --ray: {ray_problem}", file=sys.stderr)
        return 2
    encoder = args.encoder
    if args.vgg19_weights is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        encoder = args.out / "encoder-vgg19.pt"
        try:
            ImageEncoder.vgg19(args.vgg19_weights).save(encoder)
        except (ValueError, RuntimeError, FileNotFoundError) as exc:
            print(f"actaim2 collect: {args.vgg19_weights}: {exc}", file=sys.stderr)
            return 2
    config = CollectConfig(
        out=args.out, objects=tuple(objects), per_object={"random": args.random, "grasp": args.grasp, "gmm": args.gmm},
        other_splits_share=args.other_splits_share, workers=args.workers, ray_address=args.ray, seed=args.seed, robot=args.robot, perception=args.perception, render_path=args.render_path or "",
        allow_raycast=args.allow_raycast, rounds=args.rounds,
        encoder=encoder, encoder_steps=args.encoder_steps, show_progress=not args.no_progress,
        folders=tuple(folders), hull_cache=args.hull_cache, randomisation=randomisation,
        actions_per_placement=args.actions_per_placement,
    )
    try:
        report = collect(config)
    except (ValueError, FileNotFoundError) as exc:  # no label calibration split, no Vulkan device, another rig's dataset
        print(f"actaim2 collect: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # everything stored so far is complete on disk (storage.py, labelling.py)
        print(f"\nactaim2 collect: interrupted; run the same command to resume {args.out}", file=sys.stderr)
        return 130
    for stage in report["stages"]:
        rate = stage["trajectories"] / stage["seconds"] if stage["seconds"] else float("nan")
        print(f"{stage['stage']}: {stage['trajectories']} stored, {stage['skipped']} skipped, {stage['errors']} errors, "
              f"{stage['already_done']} already done, "
              f"{stage['seconds']:.0f} s ({rate:.2f} trajectories/s)")
    if "labelling" in report:
        for split, m in report["labelling"]["per_split"].items():
            print(f"visual label on {split}: accuracy {100 * m['accuracy']:.1f}%, balanced {100 * m['balanced_accuracy']:.1f}%, "
                  f"precision {100 * m['precision']:.1f}%, recall {100 * m['recall']:.1f}% ({m['n']} trajectories)")
    print(f"statistics: actaim2 stats {args.out}")
    return 0
