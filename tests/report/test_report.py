"""`actaim2 report`: the README's and docs' tables equal what the committed records give; a table
edited by hand, or a marker naming a record not in the tree, fails the check."""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from actaim2.cli import main
from actaim2.eval.evaluate_cli import _header
from actaim2.report.records import (
    MAX_BYTES,
    RECORD_FILE,
    RESULTS_DIR,
    SAMPLES_FILE,
    load_record,
    parse_tables_header,
    record_from_evaluation,
)

ROOT = Path(__file__).resolve().parents[2]
SHA = "ab" * 32


def _evaluation_folder(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A small evaluation output: 2 objects x 4 clusters x 2 repetitions, tables.md's header as
    ``actaim2 evaluate`` writes it."""
    folder.mkdir()
    samples = []
    for obj, category in (("faucet_000", "faucet"), ("table_000", "table")):
        for group in range(4):
            for repetition in range(2):
                success = (group + repetition) % 3 == 0
                samples.append({"key": f"actaim2|{obj}|{8 * repetition + group}",
                                "method": "actaim2", "split": "train_seen", "category": category,
                                "object": obj, "group": group, "repetition": repetition,
                                "success": success,
                                "mode": ["joint_0", 1 if group % 2 else -1] if success else None,
                                "phases_executed": 4, "note": "", "candidate": [0, 0, 0, 0]})
    (folder / "results.jsonl").write_text("".join(json.dumps(s) + "\n" for s in samples))
    run = {"eval_set_version": 1, "methods": {"actaim2": SHA}}
    (folder / "run.json").write_text(json.dumps(run))
    argv = ["actaim2", "evaluate", "--out", str(folder), "--workers", "2"]
    monkeypatch.setattr(sys, "argv", argv)
    args = argparse.Namespace(workers=2, ray=None, robot="panda", data=None)
    described = {"actaim2": {"path": "runs/x/policy", "weights_sha256": SHA,
                             "dataset_digest": "d" * 16,
                             "perception_digest": "p" * 16, "predictor_inputs": ["rgb", "xyz"],
                             "predictor_view": "all"}}
    header = _header(args, "full", described, "sapien", 2, 16, 16, 0, 42.0)
    (folder / "tables.md").write_text("\n".join(header) + "\n\n## Table 1\n")


def test_the_repository_tables_match_the_committed_records() -> None:
    done = subprocess.run([sys.executable, "-m", "actaim2.cli", "report", "--check"], cwd=ROOT,
                          capture_output=True, text=True, timeout=240)
    assert done.returncode == 0, done.stdout + done.stderr


def test_committed_records_are_compact_and_say_where_they_ran() -> None:
    folders = sorted(p for p in (ROOT / RESULTS_DIR).iterdir() if p.is_dir())
    assert folders
    for folder in folders:
        assert sum(p.stat().st_size for p in folder.iterdir()) < MAX_BYTES, folder
        record = load_record(ROOT, folder.name)
        for field in ("command", "checkpoints", "machine", "cores", "load_average", "seconds"):
            assert record.meta.get(field) not in (None, ""), (folder.name, field)
        assert len(record.samples) == record.meta["samples"]


def test_header_fields_round_trip(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _evaluation_folder(tmp_path / "run", monkeypatch)
    fields = parse_tables_header((tmp_path / "run" / "tables.md").read_text())
    assert fields["command"] == f"actaim2 evaluate --out {tmp_path / 'run'} --workers 2"
    assert (fields["seconds"], fields["workers"], fields["robot"]) == (42, 2, "panda")
    assert isinstance(fields["load_average"], float)
    assert fields["cores"] == os.cpu_count() and fields["machine"]
    assert fields["checkpoints"]["actaim2"]["weights_sha256"] == SHA


def test_check_fails_on_an_edited_table_and_a_missing_record(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _evaluation_folder(tmp_path / "run", monkeypatch)
    repo = tmp_path / "repo"
    out = record_from_evaluation(tmp_path / "run", repo, "tiny", machine="test machine", cores=3)
    assert sorted(p.name for p in out.iterdir()) == [RECORD_FILE, SAMPLES_FILE]
    assert json.loads((out / RECORD_FILE).read_text())["cores"] == 3
    (repo / "docs").mkdir()
    doc = repo / "docs" / "evaluation.md"
    doc.write_text("# t\n\n<!-- report:ssr tiny -->\n<!-- /report:ssr -->\n\n"
                   "<!-- report:runs tiny -->\n<!-- /report:runs -->\n")
    assert main(["report", "--check", "--root", str(repo)]) == 1  # empty tables differ
    assert main(["report", "--root", str(repo)]) == 0
    assert main(["report", "--check", "--root", str(repo)]) == 0
    text = doc.read_text()
    assert "| ActAIM2 | 37.5 [" in text and "| 16 |" in text  # 6 of 16 succeed
    assert "test machine | 3 | 2 |" in text  # machine, cores, workers rendered from the record

    doc.write_text(text.replace("| ActAIM2 | 37.5", "| ActAIM2 | 40.0"))
    assert main(["report", "--check", "--root", str(repo)]) == 1

    doc.write_text(text + "\n<!-- report:ssr gone -->\n<!-- /report:ssr -->\n")
    assert main(["report", "--check", "--root", str(repo)]) == 1
    assert not (repo / RESULTS_DIR / "gone").exists()
