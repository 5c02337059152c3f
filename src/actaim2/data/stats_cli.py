"""`actaim2 stats DATASET`: print a collected dataset's statistics as markdown."""
from __future__ import annotations

import argparse
import json
import sys


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", help="dataset folder written by `actaim2 collect`")
    parser.add_argument("--split", action="append", help="only these splits (repeatable)")


def main(args: argparse.Namespace) -> int:
    from actaim2.data import stats
    from actaim2.data.labelling import REPORT_FILE
    from actaim2.data.splits import check_no_leak
    from actaim2.data.storage import DatasetReader

    try:
        reader = DatasetReader(args.dataset)
    except (FileNotFoundError, ValueError) as exc:
        print(f"actaim2 stats: {exc}", file=sys.stderr)
        return 2
    entries = [e for e in reader.entries if not args.split or e["split"] in args.split]
    if not entries:
        print(f"actaim2 stats: {args.dataset} holds no trajectories" + (f" in splits {args.split}" if args.split else ""), file=sys.stderr)
        return 1
    check_no_leak(reader.entries)
    by_split = {s: sum(e["split"] == s for e in entries) for s in sorted({e["split"] for e in entries})}
    objects = len({(e["category"], e["instance"]) for e in entries})
    print(f"# {args.dataset}\n\n{len(entries)} trajectories on {objects} objects; per split: {by_split}\n")
    print("## Success rate per category and sampler\n")
    print(stats.success_table(entries) + "\n")
    print("## Outcome diversity (ground-truth successes)\n")
    print(stats.diversity_table(entries) + "\n")
    report_path = reader.root / REPORT_FILE
    if report_path.exists():
        print("## Visual success label\n")
        print(stats.labelling_table(json.loads(report_path.read_text())) + "\n")
    print("## Size\n")
    print(stats.size_table(entries) + "\n")
    print("## Throughput\n")
    print(stats.throughput_table(reader.root))
    return 0
