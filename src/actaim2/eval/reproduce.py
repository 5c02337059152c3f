"""Re-running stored evaluation samples by their seeds: does a run reproduce its own outcomes?

Every sample's scene and draw follow from its key (method, object, slot: ``tasks.EvalTask``'s
reset and sample seeds), so the same evaluation command re-runs any subset of it. The physics
is not bit-exact between processes (PhysX solver order, thread timing), so a few outcomes near
the success threshold may flip; the protocol asks that at least 38 of 40 re-run test samples
agree. ``actaim2 evaluate ... --reproduce DIR`` re-runs a seeded choice of DIR's samples (an
evaluation folder's ``results.jsonl`` or a committed record's ``results.jsonl.gz``) and writes
:data:`REPRODUCTION_FILE` with the agreement.
"""
from __future__ import annotations

import gzip
import json
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from actaim2.eval.results import RECORD_SAMPLES_FILE, RESULTS_FILE

REPRODUCTION_FILE = "reproduction.json"


def reference_records(folder: Path) -> dict[str, dict]:
    """Key -> sample record of an evaluation folder or a committed record folder."""
    folder = Path(folder)
    if (folder / RECORD_SAMPLES_FILE).is_file():
        with gzip.open(folder / RECORD_SAMPLES_FILE, "rt") as f:
            lines = f.read().splitlines()
    elif (folder / RESULTS_FILE).is_file():
        lines = (folder / RESULTS_FILE).read_text().splitlines()
    else:
        raise FileNotFoundError(f"{folder} holds neither {RESULTS_FILE} nor {RECORD_SAMPLES_FILE}")
    records = [json.loads(line) for line in lines if line.strip()]
    return {r["key"]: r for r in records if "error" not in r}


def choose(keys: Sequence[str], n: int, seed: int = 0) -> list[str]:
    """``n`` of ``keys`` (all when fewer), the same for the same keys and seed, in key order."""
    ordered = sorted(set(keys))
    if n >= len(ordered):
        return ordered
    picked = np.random.default_rng(seed).choice(len(ordered), size=n, replace=False)
    return [ordered[i] for i in sorted(picked)]


def agreement(reference: Mapping[str, dict], rerun: Mapping[str, dict], keys: Sequence[str]) -> dict:
    """How many of ``keys`` re-ran to the reference's outcome; the ones that did not, with both
    outcomes and largest DoF changes (a flip near the threshold reads differently from a miss)."""
    done = [k for k in keys if k in rerun and "error" not in rerun[k]]
    differ = [{"key": k, "reference": bool(reference[k]["success"]), "rerun": bool(rerun[k]["success"]),
               "reference_change": reference[k].get("largest_change"), "rerun_change": rerun[k].get("largest_change")}
              for k in done if bool(reference[k]["success"]) != bool(rerun[k]["success"])]
    return {"samples": len(done), "same": len(done) - len(differ), "not_run": len(keys) - len(done), "differ": differ}
