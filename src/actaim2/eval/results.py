"""The results of an evaluation run: one JSON line per finished task, and the run's identity.

``<out>/results.jsonl`` gets a line as each task finishes (flushed), so an interrupted run loses
at most the tasks in flight; a rerun of the same command skips every key already there. A line
cut short by a kill is dropped when the file is opened again. Tasks that raised are not written
(they are retried by the next run).

``<out>/run.json`` records what the results were made with: the evaluation set version, the
robot and rig, the planner's ``hand_half_turn``, the policies' ``keypose_alternatives``, ``mode_guidance`` and ``noise_scale``, and per method its checkpoint's weights digest. Resuming with another
checkpoint for a method already in the file is refused, so numbers of two models never mix.
"""
from __future__ import annotations

import json
import platform
from pathlib import Path
from typing import Any, Callable, Sequence

RESULTS_FILE = "results.jsonl"
RECORD_SAMPLES_FILE = "results.jsonl.gz"  # a committed record's samples (actaim2.report.records)
RUN_FILE = "run.json"


def machine_description() -> str:
    """One line naming this machine: OS, architecture, and the CPU model where Linux says it."""
    cpu = ""
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.exists():
        cpu = next((line.split(":", 1)[1].strip() for line in cpuinfo.read_text().splitlines()
                    if line.startswith("model name")), "")
    return ", ".join(p for p in (platform.system(), platform.machine(), cpu) if p)


class RunMismatchError(ValueError):
    """The output folder holds results made with something else (named in the message)."""


def check_run(out: Path, run: dict) -> dict:
    """Merge ``run`` into ``out/run.json``; refuse a different evaluation set, robot, rig, planner, number of
    fallback keyposes, mode guidance, extrinsic refinement or checkpoint."""
    path = out / RUN_FILE
    if not path.exists():
        out.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(run, indent=2, sort_keys=True))
        return run
    old = json.loads(path.read_text())
    # a run.json written before the planner option, or before pseudo-clusters were shuffled
    defaults = {"hand_half_turn": False, "pseudo_grouping": "slot mod 8", "keypose_alternatives": 0, "mode_guidance": 0.0,
                "noise_scale": 1.0, "data_collection_exploration": 0, "refine_extrinsic": False}
    for field in ("eval_set_version", "robot", "rig", "hand_half_turn", "pseudo_grouping", "keypose_alternatives",
                  "mode_guidance", "noise_scale", "data_collection_exploration", "refine_extrinsic"):
        recorded = old.get(field, defaults.get(field))
        if recorded != run.get(field, defaults.get(field)):
            flag = {"hand_half_turn": "--hand-half-turn" if recorded else "--no-hand-half-turn",
                    "keypose_alternatives": f"--keypose-alternatives {recorded}",
                    "mode_guidance": f"--mode-guidance {recorded}", "noise_scale": f"--noise-scale {recorded}",
                    "data_collection_exploration": f"--data-collection-exploration {recorded}"}.get(field)
            match = f" (or {flag} to resume it)" if flag else ""
            raise RunMismatchError(f"{out} holds results of {field} {recorded!r}, this run has {run.get(field)!r}: "
                                   f"use another --out{match}")
    for method, identity in run["methods"].items():
        before = old["methods"].get(method)
        if before is not None and before != identity:
            raise RunMismatchError(f"{out} holds {method} results made with {before}, this run has {identity}: "
                                   f"use another --out (or remove {method}'s lines)")
    merged = {**old, **run, "methods": {**old["methods"], **run["methods"]}}  # fields recorded since: written now
    path.write_text(json.dumps(merged, indent=2, sort_keys=True))
    return merged


class ResultLog:
    """Append-only JSONL of task records, keyed by ``record["key"]``."""

    def __init__(self, out: Path):
        self.path = Path(out) / RESULTS_FILE
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.records: dict[str, dict] = {}
        if self.path.exists():
            text = self.path.read_text()
            complete = text[: text.rfind("\n") + 1]  # a line without its newline was cut by a kill
            if complete != text:
                self.path.write_text(complete)
            for line in complete.splitlines():
                if line.strip():
                    record = json.loads(line)
                    self.records[record["key"]] = record

    @property
    def done(self) -> set[str]:
        return set(self.records)

    def append(self, record: dict) -> None:
        with open(self.path, "a") as f:
            f.write(json.dumps(record) + "\n")
            f.flush()
        self.records[record["key"]] = record

    def run(self, make: Callable[[Any], Any], setup: Any, tasks: Sequence[Any], workers: int, ray: str | None = None,
            show_progress: bool = True, unit: str = "sample") -> int:
        """Run ``tasks`` on ``make(setup)`` workers (:func:`actaim2.parallel.run_unordered`) under a progress bar,
        appending each record as it comes; a record with an error is printed, not kept (a rerun retries it).
        Returns the number of errors."""
        from tqdm import tqdm

        from actaim2.parallel import run_unordered

        if not tasks:  # all done: no worker (a simulator) to build
            return 0
        errors = 0
        bar = tqdm(total=len(tasks), unit=unit, disable=not show_progress)
        try:
            for record in run_unordered(make, setup, tasks, workers, ray):
                if "error" in record:
                    errors += 1
                    bar.write(f"{record['key']}: {record['error']}")
                else:
                    self.append(record)
                bar.update(1)
        finally:
            bar.close()
        return errors
