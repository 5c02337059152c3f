"""`actaim2 eval-compare`: two `actaim2 evaluate` runs of the same samples, paired by key.

    actaim2 eval-compare runs/eval runs/half_turn --out runs/half_turn/compare.md

For every (method, split, category) both runs finished: each run's SSR with its Wilson interval,
the discordant samples (succeeded only in A, only in B) and the exact McNemar p-value
(``paired.py``), and the share that ran all four phases. The header says what differs between
the two runs' ``run.json`` (a planner option, a checkpoint digest), so the table names its change.
"""
from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("a", type=Path, help="results folder of run A (the reference)")
    parser.add_argument("b", type=Path, help="results folder of run B (the change)")
    parser.add_argument("--out", type=Path, help="also write the markdown here")


def run_differences(a: dict, b: dict) -> list[str]:
    """What the two run.json files record differently, one ``field: A -> B`` per line."""
    def flat(run: dict) -> dict:
        return {**{k: v for k, v in run.items() if k != "methods"}, **{f"checkpoint of {m}": d for m, d in run["methods"].items()}}

    flat_a, flat_b = flat(a), flat(b)
    return [f"{k}: {flat_a.get(k, '-')} -> {flat_b.get(k, '-')}" for k in sorted(set(flat_a) | set(flat_b))
            if flat_a.get(k) != flat_b.get(k)]


def main(args: argparse.Namespace) -> int:
    from actaim2.eval.evalset import SPLIT_TITLES
    from actaim2.eval.methods import METHODS
    from actaim2.eval.paired import UnpairedError, pair_records, paired_table
    from actaim2.eval.results import RESULTS_FILE, RUN_FILE, ResultLog

    for folder in (args.a, args.b):
        if not (folder / RESULTS_FILE).exists() or not (folder / RUN_FILE).exists():
            print(f"error: {folder} holds no evaluation ({RESULTS_FILE} and {RUN_FILE}): give an `actaim2 evaluate --out` folder",
                  file=sys.stderr)
            return 2
    a, b = ResultLog(args.a).records, ResultLog(args.b).records
    try:
        pairs = pair_records(a, b)
    except UnpairedError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    changes = run_differences(json.loads((args.a / RUN_FILE).read_text()), json.loads((args.b / RUN_FILE).read_text()))
    lines = [f"# {args.a} (A) against {args.b} (B), paired by sample", "",
             f"`actaim2 eval-compare {' '.join(shlex.quote(str(x)) for x in (args.a, args.b))}`", "",
             "What differs (run.json): " + ("; ".join(changes) if changes else "nothing recorded"), "",
             f"{len(pairs)} samples in both; {len(a) - len(pairs)} only in A, {len(b) - len(pairs)} only in B "
             "(unfinished or other rows: not counted).", "",
             *paired_table(pairs, {m: METHODS[m].title for m in METHODS}, SPLIT_TITLES)]
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0
