"""Committed result records: what the README's and docs' tables are computed from.

A record is a folder ``results/<name>/`` in the repository:

- ``record.json``: what made the results: the command, per method its checkpoint (path, weights
  SHA-256, dataset and perception digests), the run's options (``run.json`` of an evaluation),
  and where it ran: ``machine``, ``cores``, ``workers``, ``load_average`` (the 1-minute load when
  the tables were written), ``seconds`` (wall time of the session that finished the run),
  ``samples``, a free ``note`` and ``source`` (where the raw run came from);
- ``results.jsonl.gz``: the evaluation's per-sample records (``eval/results.py``), gzipped;
  for a collection (``kind`` "collection"), one line per trajectory: its index entry without
  picture offsets and action (object, category, sampler, ground-truth success, DoF change,
  whether the robot touched the object, the visual success label where the dataset is
  labelled), and one per skipped trajectory (``skipped`` true).

:func:`record_from_evaluation` makes one from an ``actaim2 evaluate`` output folder, reading the
header lines of its ``tables.md`` (``evaluate_cli._header``) for the command, time and load;
:func:`record_from_collection` from an ``actaim2 collect`` dataset (its ``dataset.json``, stage
runs and index); :func:`record_from_validation` from an ``actaim2 validate`` folder (kind
"validation": one line per eps source and keypose with the predictor's errors).
"""
from __future__ import annotations

import gzip
import json
import os
import re
from dataclasses import dataclass
from pathlib import Path

from actaim2.data.stats import RUNS_FILE
from actaim2.data.storage import INDEX_FILE, LABELS_FILE, SKIPPED_FILE
from actaim2.eval.results import RECORD_SAMPLES_FILE as SAMPLES_FILE
from actaim2.eval.results import RESULTS_FILE, RUN_FILE, machine_description

RESULTS_DIR = "results"
RECORD_FILE = "record.json"
VALIDATION_FILE = "validation.json"  # actaim2 validate's report (train/validation.py)
MAX_BYTES = 2 * 1024 * 1024  # a record's files together stay under this

_COMMAND = re.compile(r"^Command: `(?P<command>.*)`$")
_RUN = re.compile(r"^- this run: (?P<seconds>\d+) s on (?P<workers>\d+) worker\(s\)"
                  r"(?: \(Ray [^)]*\))?, load average (?P<load>[\d.]+), "
                  r"render path (?P<render>\S+), robot (?P<robot>\S+)$")
_METHOD = re.compile(r"^- (?P<method>\w+): checkpoint `(?P<path>[^`]*)`, "
                     r"weights sha256 `(?P<sha>\w+)`, "
                     r"dataset (?P<dataset>\S+), views (?P<views>\S+), ")
_MACHINE = re.compile(r"^- machine: (?P<machine>.*), (?P<cores>\d+) cores$")
_DATASET = re.compile(r"^- dataset `(?P<path>[^`]*)` digest (?P<digest>\S+)$")


class RecordError(ValueError):
    """A record is missing, incomplete or too large (named in the message)."""


@dataclass(frozen=True)
class Record:
    name: str
    meta: dict
    samples: list[dict]

    @property
    def label(self) -> str:
        """What was evaluated: each method's title and its weights' first 8 hex digits."""
        from actaim2.eval.methods import METHODS

        return ", ".join(f"{METHODS[m].title} {c['weights_sha256'][:8]}"
                         for m, c in self.meta["checkpoints"].items())


def parse_tables_header(text: str) -> dict:
    """The fields of an evaluation ``tables.md`` header: command, seconds, workers, load average,
    render path, robot, machine and cores (when the header has them), per method
    its checkpoint, and the ``--data`` dataset if given."""
    fields: dict = {"checkpoints": {}}
    for line in text.splitlines():
        if m := _COMMAND.match(line):
            fields["command"] = m["command"]
        elif m := _RUN.match(line):
            fields.update(seconds=int(m["seconds"]), workers=int(m["workers"]),
                          load_average=float(m["load"]), render_path=m["render"], robot=m["robot"])
        elif m := _METHOD.match(line):
            fields["checkpoints"][m["method"]] = {"path": m["path"], "weights_sha256": m["sha"],
                                                  "dataset_digest": m["dataset"],
                                                  "perception_digest": m["views"]}
        elif m := _MACHINE.match(line):
            fields.update(machine=m["machine"], cores=int(m["cores"]))
        elif m := _DATASET.match(line):
            fields["dataset"] = {"path": m["path"], "digest": m["digest"]}
        elif line.startswith("## "):
            break
    missing = [k for k in ("command", "seconds") if k not in fields]
    if missing or not fields["checkpoints"] and "dataset" not in fields:
        raise RecordError(f"tables.md header lacks {missing or 'a checkpoint or dataset line'}")
    return fields


def record_from_evaluation(run_dir: Path, root: Path, name: str, *, machine: str | None = None,
                           cores: int | None = None, note: str = "", source: str = "") -> Path:
    """Write ``root/results/<name>/`` from an evaluation folder (``results.jsonl``, ``run.json``,
    ``tables.md``); machine and cores default to the header's, else this machine's. Returns the
    record's folder."""
    run_dir = Path(run_dir)
    header = parse_tables_header((run_dir / "tables.md").read_text())
    lines = [line for line in (run_dir / RESULTS_FILE).read_text().splitlines() if line.strip()]
    meta = {"name": name, "kind": "evaluation", **header,
            "run": json.loads((run_dir / RUN_FILE).read_text()), "samples": len(lines),
            "machine": machine or header.get("machine") or machine_description(),
            "cores": cores or header.get("cores") or os.cpu_count(),
            "note": note, "source": source or str(run_dir)}
    return _write_record(root, name, meta, lines)


COLLECTION_FIELDS = ("id", "object_id", "category", "split", "sampler", "index", "gt_success",
                     "dof_change", "touched", "attempts", "worker_seconds")


def record_from_collection(dataset: Path, root: Path, name: str, *, command: str,
                           note: str = "", source: str = "") -> Path:
    """Write ``root/results/<name>/`` from a collected dataset; ``command`` is the collect
    command that made it (a dataset does not keep its command line). Returns the folder."""
    dataset = Path(dataset)

    def lines(path: Path) -> list[dict]:
        return [json.loads(t) for t in path.read_text().splitlines() if t.strip()] if path.exists() else []

    stages = lines(dataset / RUNS_FILE)
    visual = {label["id"]: bool(label["success"]) for label in lines(dataset / LABELS_FILE)}
    samples = [{k: e[k] for k in COLLECTION_FIELDS if k in e} for e in lines(dataset / INDEX_FILE)]
    for s in samples:
        if s["id"] in visual:
            s["visual_success"] = visual[s["id"]]
    samples += [{"id": s["id"], "sampler": s["sampler"], "category": s["category"], "skipped": True,
                 "reasons": s["reasons"]} for s in lines(dataset / SKIPPED_FILE)]
    meta = {"name": name, "kind": "collection", "command": command, "checkpoints": {},
            "dataset": {"path": str(dataset), "info": json.loads((dataset / "dataset.json").read_text())},
            "stages": stages, "samples": len(samples),
            "seconds": round(sum(s["seconds"] for s in stages)),
            "workers": max((s["workers"] for s in stages), default=0),
            "load_average": max((s.get("load_average", 0.0) for s in stages), default=0.0),
            "machine": machine_description(), "cores": os.cpu_count(),
            "note": note, "source": source or str(dataset)}
    return _write_record(root, name, meta, [json.dumps(s, sort_keys=True) for s in samples])


def record_from_validation(run_dir: Path, root: Path, name: str, *, command: str,
                           note: str = "", source: str = "") -> Path:
    """Write ``root/results/<name>/`` from an ``actaim2 validate`` folder (its ``validation.json``);
    ``command`` is the validate command (the report does not keep it). One line per (eps fed,
    keypose) with the predictor's errors; the selector's figures in the record. Returns the
    folder."""
    report = json.loads((Path(run_dir) / VALIDATION_FILE).read_text())
    lines = [json.dumps({"eps": eps, "keypose": keypose, **figures}, sort_keys=True)
             for eps, by_keypose in report["actions"].items() for keypose, figures in by_keypose.items()]
    meta = {"name": name, "kind": "validation", "command": command,
            "checkpoints": {"actaim2": {"path": report["checkpoint"], "weights_sha256": report["weights_sha256"],
                                        "dataset_digest": report["dataset_digest"]}},
            "dataset": {"path": report["dataset"]}, "split": report["split"],
            "noise_scale": report["noise_scale"], "selector": report["selector"], "samples": len(lines),
            "seconds": 0, "workers": 0, "load_average": os.getloadavg()[0],
            "machine": machine_description(), "cores": os.cpu_count(), "note": note,
            "source": source or str(run_dir)}
    return _write_record(root, name, meta, lines)


def record_from_samples(root: Path, name: str, meta: dict, samples: list[dict]) -> Path:
    """Write ``root/results/<name>/`` from a measurement's own samples and fields (``meta``: at least
    ``kind``, ``command``, ``seconds``, ``samples``, ``machine``, ``cores``). Returns the folder."""
    return _write_record(root, name, {"name": name, **meta}, [json.dumps(s, sort_keys=True) for s in samples])


def _write_record(root: Path, name: str, meta: dict, lines: list[str]) -> Path:
    out = Path(root) / RESULTS_DIR / name
    out.mkdir(parents=True, exist_ok=True)
    (out / RECORD_FILE).write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    # mtime 0: the same results give the same bytes
    with gzip.GzipFile(out / SAMPLES_FILE, "wb", compresslevel=9, mtime=0) as f:
        f.write(("\n".join(lines) + "\n").encode())
    size = sum(p.stat().st_size for p in out.iterdir())
    if size > MAX_BYTES:
        raise RecordError(f"{out} holds {size} bytes, above the {MAX_BYTES} a record may take")
    return out


def load_record(root: Path, name: str) -> Record:
    """The record ``root/results/<name>``; :class:`RecordError` if it is not in the tree."""
    folder = Path(root) / RESULTS_DIR / name
    if not (folder / RECORD_FILE).is_file():
        raise RecordError(f"record {name!r} is not in the tree ({folder / RECORD_FILE} missing)")
    meta = json.loads((folder / RECORD_FILE).read_text())
    samples: list[dict] = []
    if (folder / SAMPLES_FILE).is_file():
        with gzip.open(folder / SAMPLES_FILE, "rt") as f:
            samples = [json.loads(line) for line in f if line.strip()]
    return Record(name, meta, samples)
