"""`actaim2 bench models`: parameters, latency and training step of the selectors and the action predictor.

Targets (2 CPU cores): selector sample p50 <= 5 ms; predictor forward with the 3-D
decode p50 <= 20 ms; predictor training step at batch 8 <= 300 ms. Other jobs on the machine
stretch wall times: each row also gives this process's CPU time and the load average.
"""
from __future__ import annotations

import argparse
import json


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    parser.add_argument("--device", default="cpu", help="cpu or cuda")
    parser.add_argument("--repeats", type=int, default=100, help="timed calls per latency row")
    parser.add_argument("--only", choices=["selector", "predictor"], help="bench one model only")
    parser.add_argument("--json", action="store_true", help="print the rows as JSON instead of markdown")


def main(args: argparse.Namespace) -> int:
    from actaim2.bench.models import bench_predictor, markdown_table
    from actaim2.bench.selector import bench_selector

    rows = []
    if args.only in (None, "selector"):
        rows += bench_selector(device=args.device, threads=args.threads, repeats=args.repeats)
    if args.only in (None, "predictor"):
        rows += bench_predictor(device=args.device, threads=args.threads, repeats=args.repeats)
    print(json.dumps(rows, indent=2) if args.json else markdown_table(rows))
    return 0
