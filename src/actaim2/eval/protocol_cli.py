"""`actaim2 protocol`: write the protocol lock before any test figure; count the ledger's runs.

Examples:
    actaim2 protocol lock --catalogue partnet --partnet-root ~/partnet-mobility \\
        --recipe recipes/real.yaml --checkpoint runs/s0/policy --checkpoint runs/s1/policy \\
        --checkpoint runs/s2/policy                      # -> results/protocol.lock
    actaim2 protocol ledger                              # the --final runs so far
    actaim2 protocol compare runs/test-s0 runs/test-s1 runs/test-s2   # both rules, seeds pooled

The lock's format and the rules it enforces: actaim2.protocol.lock and docs/evaluation.md
("Protocol").
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

from actaim2.data.collect_cli import add_catalogue_arguments
from actaim2.protocol.lock import LEDGER_FILE, LOCK_FILE


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True)
    lock = sub.add_parser(
        "lock", help="freeze the recipe, seeds' checkpoints, evaluation set and test objects"
    )
    lock.add_argument(
        "--recipe",
        type=Path,
        required=True,
        help="the file that makes the checkpoints (its sha256 is locked)",
    )
    lock.add_argument(
        "--checkpoint",
        type=Path,
        action="append",
        required=True,
        metavar="STEM",
        help="a seed's policy checkpoint (repeatable, seed 0 first: the committed one)",
    )
    lock.add_argument(
        "--samples-per-group",
        type=int,
        default=8,
        help="samples per cluster and pseudo-cluster (default 8)",
    )
    lock.add_argument(
        "--splits",
        default="test_unseen_instance,test_unseen_category",
        help="the test splits to lock",
    )
    lock.add_argument(
        "--lock", type=Path, default=LOCK_FILE, help=f"where to write it (default {LOCK_FILE})"
    )
    add_catalogue_arguments(lock)
    compare = sub.add_parser("compare", help="ActAIM2 against Data Collection by the protocol's "
                                             "rules, over each seed's evaluation run")
    compare.add_argument("runs", type=Path, nargs="+",
                         help="evaluation output folders, one per seed")
    compare.add_argument("--method", default="actaim2", help="the row judged (default actaim2)")
    compare.add_argument("--baseline", default="data_collection",
                         help="the row it must beat (default data_collection)")
    compare.add_argument("--baseline-from", type=Path, nargs="+", metavar="DIR",
                         help="take the baseline's records from these evaluation folders instead (one "
                              "for every run, or one per run in the same order): a baseline evaluated "
                              "once on the same scenes and compared with several candidates")
    compare.add_argument("--halvings", type=int, default=100, help="random halvings (>= 100)")
    compare.add_argument("--rounds", type=int, default=2000, help="bootstrap rounds")
    compare.add_argument("--out", type=Path, help="also write the markdown there")
    ledger = sub.add_parser("ledger", help="count the --final runs")
    ledger.add_argument(
        "--ledger", type=Path, default=LEDGER_FILE, help=f"the ledger (default {LEDGER_FILE})"
    )


def main(args: argparse.Namespace) -> int:
    return {"lock": _lock, "compare": _compare, "ledger": _ledger}[args.action](args)


def _compare(args: argparse.Namespace) -> int:
    from actaim2.eval.paired import comparison
    from actaim2.eval.results import RESULTS_FILE, ResultLog

    try:
        extra = args.baseline_from or []
        if len(extra) not in (0, 1, len(args.runs)):
            raise ValueError(f"--baseline-from: {len(extra)} folders for {len(args.runs)} runs (give one, or "
                             f"one per run)")
        missing = [str(run) for run in [*args.runs, *extra] if not (run / RESULTS_FILE).is_file()]
        if missing:
            raise ValueError(f"no {RESULTS_FILE} in {', '.join(missing)}")
        runs = [list(ResultLog(run).records.values()) for run in args.runs]
        if extra:
            baselines = [[r for r in ResultLog(d).records.values() if r["method"] == args.baseline]
                         for d in (extra * len(args.runs) if len(extra) == 1 else extra)]
            runs = [[r for r in records if r["method"] != args.baseline] + base
                    for records, base in zip(runs, baselines)]
        text = "\n".join(comparison(runs, args.method, args.baseline, args.halvings, args.rounds))
    except ValueError as exc:
        print(f"actaim2 protocol compare: {exc}", file=sys.stderr)
        return 2
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")
    return 0


def _lock(args: argparse.Namespace) -> int:
    from actaim2.data.real_objects import catalogue_folders, partnet_root
    from actaim2.data.splits import PARTNET
    from actaim2.eval.checkpoints import describe
    from actaim2.eval.evalset import EVAL_SET_VERSION
    from actaim2.protocol.lock import ProtocolLock, file_sha256, success_rule

    try:
        if args.catalogue != PARTNET.name:
            raise ValueError(
                "the protocol locks the partnet catalogue's test splits: pass --catalogue partnet"
            )
        splits = tuple(s for s in args.splits.split(",") if s)
        if not set(splits) <= set(PARTNET.test):
            raise ValueError(
                f"--splits {args.splits}: a lock holds test splits only "
                f"({', '.join(PARTNET.test)})"
            )
        folders = catalogue_folders(partnet_root(args.partnet_root), splits)
        objects = {s: tuple(f.object_id for f in folders if f.split == s) for s in splits}
        digests = tuple(str(describe(stem)["weights_sha256"]) for stem in args.checkpoint)
        lock = ProtocolLock(
            str(args.recipe),
            file_sha256(args.recipe),
            digests,
            EVAL_SET_VERSION,
            args.samples_per_group,
            objects,
            success_rule(),
        )
        lock.write(args.lock)
    except (ValueError, FileNotFoundError) as exc:
        print(f"actaim2 protocol lock: {exc}", file=sys.stderr)
        return 2
    counts = ", ".join(f"{s} {len(v)}" for s, v in objects.items())
    print(
        f"wrote {args.lock}: {len(digests)} seed(s), evaluation set {EVAL_SET_VERSION}, "
        f"{args.samples_per_group} per group, objects {counts}, sha256 {lock.sha256[:12]}; commit "
        "it before any test run"
    )
    return 0


def _ledger(args: argparse.Namespace) -> int:
    from actaim2.protocol.lock import read_ledger

    try:
        runs = read_ledger(args.ledger)
    except ValueError as exc:
        print(f"actaim2 protocol ledger: {exc}", file=sys.stderr)
        return 2
    per_split = Counter(s for r in runs for s in r.get("splits", {}))
    detail = ", ".join(f"{s}: {n}" for s, n in sorted(per_split.items()))
    print(f"{len(runs)} --final run(s) in {args.ledger}" + (f" ({detail})" if detail else ""))
    return 0
