"""`actaim2 report`: regenerate every marked table of README.md and docs/ from ``results/``.

    actaim2 report                  # rewrite the tables between <!-- report:... --> markers
    actaim2 report --check          # exit 1: a table differs from its records, a record is missing
    actaim2 report --add runs/eval_x --name NAME   # an evaluation folder -> results/NAME
    actaim2 report --add data/ds --name NAME --command "actaim2 collect ..."   # a collected dataset
    actaim2 report --add runs/x --name NAME --command "actaim2 validate ..."   # validation figures
"""
from __future__ import annotations

import argparse
import difflib
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--root", type=Path, default=Path("."),
                        help="the repository (README.md, docs/, results/); default: here")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 if a table differs from what its records give")
    parser.add_argument("--add", type=Path, metavar="RUN_DIR",
                        help="make a record of this actaim2 evaluate output (or actaim2 collect "
                             "dataset), then regenerate")
    parser.add_argument("--command", help="the collect or validate command that made the dataset or validation "
                                          "figures (--add of either: they do not keep their command line)")
    parser.add_argument("--name", help="the record's folder name under results/ (with --add)")
    parser.add_argument("--machine",
                        help="the run's machine (with --add; default: tables.md's, else this)")
    parser.add_argument("--cores", type=int,
                        help="its CPU cores (with --add; default: as --machine)")
    parser.add_argument("--note", default="", help="a remark kept in the record (with --add)")
    parser.add_argument("--source", default="",
                        help="where the run came from (with --add; default: RUN_DIR)")


def main(args: argparse.Namespace) -> int:
    from actaim2.eval.results import RESULTS_FILE
    from actaim2.report.markers import blocks, rewrite
    from actaim2.report.records import (
        VALIDATION_FILE,
        RecordError,
        record_from_collection,
        record_from_evaluation,
        record_from_validation,
    )

    root = args.root.resolve()
    try:
        if args.add is not None:
            if not args.name:
                print("report: --add needs --name", file=sys.stderr)
                return 2
            if (args.add / VALIDATION_FILE).is_file() and not (args.add / RESULTS_FILE).is_file():
                if not args.command:
                    print("report: --add of a validation needs --command", file=sys.stderr)
                    return 2
                out = record_from_validation(args.add, root, args.name, command=args.command,
                                             note=args.note, source=args.source)
            elif (args.add / "dataset.json").is_file():
                if not args.command:
                    print("report: --add of a dataset needs --command", file=sys.stderr)
                    return 2
                out = record_from_collection(args.add, root, args.name, command=args.command,
                                             note=args.note, source=args.source)
            else:
                out = record_from_evaluation(args.add, root, args.name, machine=args.machine,
                                             cores=args.cores, note=args.note, source=args.source)
            print(f"record {out.relative_to(root)}")
        if args.check:
            stale = [b for b in blocks(root) if b.body != b.expected]
            for b in stale:
                print(f"{b.path.relative_to(root)}: report:{b.table} {' '.join(b.records)} "
                      "differs from its records:")
                sys.stdout.writelines(difflib.unified_diff(
                    b.body.splitlines(True), b.expected.splitlines(True),
                    "in the file", "from the records"))
            if stale:
                print(f"{len(stale)} table(s) differ: run `actaim2 report`")
                return 1
            print("every report table matches its records")
            return 0
        for path in rewrite(root):
            print(f"rewrote {path.relative_to(root)}")
    except RecordError as e:
        print(f"report: {e}", file=sys.stderr)
        return 1
    return 0
