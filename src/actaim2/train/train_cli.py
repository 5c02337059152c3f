"""`actaim2 train`: train the policy (selector, predictor, joint) on a collected dataset.

Examples:
    actaim2 train --data data/ds --out runs/cpu                       # CGMVAE + predictor, CPU default config
    actaim2 train --data data/ds --out runs/cpu --resume              # continue an interrupted run
    actaim2 train --data data/pm --out runs/pm --catalogue partnet    # no val/test object in it
    actaim2 train --data data/ds --out runs/cvae --selector cvae --phases selector joint \\
        --init-from runs/cpu/goal_rvt                                 # a baseline on the Goal-RVT predictor
    torchrun --nproc-per-node 2 --master-addr 127.0.0.1 -m actaim2.cli train --data data/ds --out runs/ddp  # DDP

Views of the visually successful ``train_seen`` trajectories are rendered once and cached in
the dataset folder; 10% of those trajectories (by id hash) are held out for validation curves.
After the predictor phase its weights are also saved as ``<out>/goal_rvt`` (the Goal-RVT
baseline: the predictor fed the true z). Beside each model goes the dataset's encoder E
(``<stem>.encoder.pt``), which fine-tuning and Goal-RVT need to embed new observations.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

from actaim2.data.collect_cli import add_catalogue_arguments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", type=Path, required=True, help="dataset folder (actaim2 collect)")
    parser.add_argument("--out", type=Path, required=True, help="run folder: checkpoints, history.jsonl, tensorboard/")
    add_catalogue_arguments(parser)
    parser.add_argument("--config", default="cpu_default", help="training YAML, or a bundled name (cpu_default, gpu_rvt)")
    parser.add_argument("--perception", default="ring5", help="perception configuration: rig name or YAML")
    parser.add_argument("--selector", choices=["cgmvae", "cvae", "vqvae"], help="override the config's selector kind")
    parser.add_argument("--phases", nargs="+", choices=["selector", "predictor", "joint"], help="override the config's phases")
    parser.add_argument("--init-from", type=Path, help="start from this policy checkpoint (e.g. <run>/goal_rvt)")
    parser.add_argument("--resume", action="store_true", help="continue from <out>/train_state")
    parser.add_argument("--device", choices=["auto", "cpu", "cuda"], help="override the config's device")
    parser.add_argument("--seed", type=int, help="override the config's training seed (initialisation, hold-out, "
                                                 "batches, noise): one seed of a recipe")
    add_threads_argument(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def add_threads_argument(parser: argparse.ArgumentParser) -> None:
    """``--threads``, shared with ``actaim2 validate``: both run torch on the CPU, often beside other work."""
    parser.add_argument("--threads", type=int, default=0,
                        help="torch CPU threads (0: torch's default, one per core). Beside other CPU work (evaluation "
                             "workers, a collection) use 1: spinning OpenMP threads made validation several times slower there")


def main(args: argparse.Namespace) -> int:
    import dataclasses

    import torch.distributed as dist

    from actaim2.artifact.checkpoint import perception_record
    from actaim2.data.labelling import dataset_encoder, embeddings_encoder_digest
    from actaim2.data.splits import TRAINING_SPLITS
    from actaim2.data.storage import dataset_digest
    from actaim2.models.view_geometry import CubePlacement
    from actaim2.perception.config import load_perception_config
    from actaim2.train.config import load_config
    from actaim2.train.data import ensure_cache, holdout_split, open_cache
    from actaim2.train.distributed import init_distributed, set_cpu_threads, shutdown
    from actaim2.train.loop import Trainer

    if args.threads < 0:
        print(f"actaim2 train: --threads {args.threads} is negative")
        return 2
    if args.catalogue == "partnet":
        from actaim2.data.real_objects import check_training_objects, partnet_root, partnet_splits
        from actaim2.data.storage import DatasetReader

        try:  # no trajectory of a val or test object may reach the models
            splits = partnet_splits(partnet_root(args.partnet_root))
            check_training_objects(DatasetReader(args.data).entries, splits)
        except (ValueError, FileNotFoundError) as exc:
            print(f"actaim2 train: {exc}")
            return 2
    set_cpu_threads(args.threads)
    config = load_config(args.config)
    changes = {}
    if args.selector:
        changes["selector"] = dataclasses.replace(config.selector, kind=args.selector)
    if args.phases:
        changes["phases"] = tuple(args.phases)
    if args.device:
        changes["device"] = args.device
    if args.seed is not None:
        changes["seed"] = args.seed
    config = dataclasses.replace(config, **changes)
    ctx = init_distributed(config.device)
    perception_config = load_perception_config(args.perception)
    record = perception_record(perception_config)
    if ctx.is_main:  # one rank renders the cache (the torch datasets check the dataset's capture fields), the others wait
        ensure_cache(args.data, perception_config, list(TRAINING_SPLITS), not args.no_progress)
    if ctx.distributed:
        dist.barrier()
    placement = CubePlacement.of(perception_config)
    data = open_cache(args.data, perception_config, list(TRAINING_SPLITS))
    train_rows, val_rows = holdout_split(data.ids, config.validation_fraction, config.seed)
    trainer = Trainer(config, data.subset(train_rows), data.subset(val_rows), placement, record, dataset_digest(args.data),
                      args.out, ctx, args.init_from, show_progress=not args.no_progress)
    if args.resume and not trainer.resume():
        print(f"no {args.out}/train_state to resume from: starting afresh")
    # The encoder E of the task embeddings the selector learns, recorded in the checkpoint: demonstrations
    # for fine-tuning must be embedded by the same E (bag2dataset --checkpoint and finetune check it).
    # Set after a resume too: the state's dataset digest, which covers embeddings.npz, is this dataset's.
    trainer.lineage["encoder_digest"] = embeddings_encoder_digest(args.data)
    trainer.encoder_file = dataset_encoder(args.data)
    if trainer.lineage["encoder_digest"] is not None and trainer.encoder_file is None and ctx.is_main:
        print(f"actaim2 train: no encoder file of digest {trainer.lineage['encoder_digest']} found for {args.data}: "
              f"the checkpoints will have none beside them (fine-tuning then needs bag2dataset --encoder)")
    results = trainer.run()
    if ctx.is_main:
        print(json.dumps({phase: {"steps": r.steps, "seconds": round(r.seconds, 1), "last": r.last_metrics}
                          for phase, r in results.items()}, indent=2))
    shutdown()
    return 0
