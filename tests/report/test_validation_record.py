"""`actaim2 validate`'s figures as a committed record, and the `errors` table made of it."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from actaim2.cli import main as cli
from actaim2.report.records import RecordError, load_record
from actaim2.report.tables import errors_table


def _validation(folder: Path) -> None:
    figures = {"keyframes": 4, "translation_median_mm": 12.4, "translation_p90_mm": 30.6,
               "rotation_median_deg": 8.25, "rotation_p90_deg": 20.0, "gripper_accuracy": 1.0}
    actions = {eps: {kp: {**figures, "translation_median_mm": figures["translation_median_mm"] + 10 * k + (eps == "true")}
                     for k, kp in enumerate(("all", "init", "reach", "grasp", "manipulate"))}
               for eps in ("reconstructed", "true")}
    folder.mkdir()
    (folder / "validation.json").write_text(json.dumps({
        "checkpoint": "runs/x/policy", "weights_sha256": "ab" * 32, "dataset": "data/v", "dataset_digest": "d1",
        "split": "val", "noise_scale": 0.0, "actions": actions, "selector": {"trajectories": 1}}))


def test_a_validation_becomes_a_record_and_its_errors_table(tmp_path) -> None:
    _validation(tmp_path / "run")
    assert cli(["report", "--root", str(tmp_path), "--add", str(tmp_path / "run"), "--name", "v"]) == 2  # no --command
    assert cli(["report", "--root", str(tmp_path), "--add", str(tmp_path / "run"), "--name", "v",
                "--command", "actaim2 validate runs/x"]) == 0
    record = load_record(tmp_path, "v")
    assert record.meta["kind"] == "validation" and record.meta["split"] == "val" and len(record.samples) == 10
    lines = errors_table([record])
    assert lines[2] == "| `v` | val | all | 4 | 12 / 31 | 13 / 31 | 8.2 / 8.2 |"
    assert lines[4].startswith("| `v` | val | reach | 4 | 32 / 31 | 33 / 31 |")
    with pytest.raises(RecordError, match="not a validation"):
        errors_table([record.__class__("c", {"kind": "collection"}, [])])
