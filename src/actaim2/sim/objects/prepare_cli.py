"""`actaim2 prepare-objects`: decompose real PartNet-Mobility folders' collision meshes into the hull cache.

Examples:
    actaim2 prepare-objects ~/data/partnet-mobility                 # a folder of object folders
    actaim2 prepare-objects ~/data/partnet-mobility/45780 --cache /fast/hulls --workers 4

Run it once per dataset before simulating (the loader reads the hulls from the cache, and a
mesh without an entry is one convex hull, with a warning). Interrupted, it resumes: finished
meshes are cache entries. See actaim2.sim.objects.hulls for the rule and the parameters.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folders", nargs="+", type=Path, help="object folders, or folders of object folders")
    parser.add_argument("--cache", type=Path, default=None, help="hull cache folder (default $ACTAIM2_CACHE/hulls or ~/.cache/actaim2/hulls)")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="decomposition processes (default: one per CPU)")


def main(args: argparse.Namespace) -> int:
    from actaim2.sim.objects.errors import ObjectLoadError
    from actaim2.sim.objects.hulls import HullCache
    from actaim2.sim.objects.prepare import find_object_folders, prepare_objects

    cache = HullCache(args.cache)
    try:
        folders = [f for path in args.folders for f in find_object_folders(path)]
        started = time.perf_counter()
        reports = prepare_objects(folders, cache, max(1, args.workers))
    except ObjectLoadError as exc:
        print(f"actaim2 prepare-objects: {exc}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - started
    print("| object | scale | meshes | decomposed | convex | small | already cached | hulls | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in reports:
        print(f"| {r.folder.name} | {r.scale:.3f} | {r.meshes} | {r.count('decomposed')} | {r.count('convex')} | {r.small} "
              f"| {r.count('cached')} | {r.hulls} | {r.cpu_s:.1f} |")
    load = os.getloadavg()
    print(f"\n{len(reports)} object(s) in {wall:.1f} s wall with {args.workers} worker(s), cache {cache.root} "
          f"(load average {load[0]:.1f})")
    return 0
