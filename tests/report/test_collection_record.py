"""A collected dataset as a committed record, and the sampler tables ``actaim2 report`` makes of
it: counts known by construction."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from actaim2.report.records import RecordError, load_record, record_from_collection
from actaim2.report.tables import dof_change_table, label_table, runs_table, samplers_table


def _dataset(folder: Path) -> None:
    """Cabinet A (2 objects' worth of trajectories under one category) and a table:
    random: 10 executed on the cabinet, 3 successes, 2 more that moved 10 %, 1 touched without
    moving, 4 never touched; 1 skipped. grasp: 5 on the table, 1 success, the rest untouched."""
    folder.mkdir()
    entries = []

    def add(obj: str, category: str, sampler: str, change: float, touched: bool) -> None:
        k = sum(e["sampler"] == sampler for e in entries)  # numbered per sampler, as collect does per object
        entries.append({"id": f"{obj}-{sampler}-{k:05d}", "object_id": obj, "category": category,
                        "split": "train_seen", "sampler": sampler, "index": k,
                        "gt_success": abs(change) > 0.3, "dof_change": [0.0, change], "touched": touched,
                        "attempts": 1, "worker_seconds": 1.0, "chunk": 0, "offset": 0, "size": 10,
                        "action": [0.0] * 12})

    for k, (change, touched) in enumerate([(0.5, True)] * 3 + [(0.1, True)] * 2 + [(0.0, True)] + [(0.0, False)] * 4):
        add("cab_a" if k % 2 else "cab_b", "storage_furniture", "random", change, touched)
    add("tab", "table", "grasp", -0.4, True)
    for _ in range(4):
        add("tab", "table", "grasp", 0.0, False)
    entries.append({**entries[0], "id": "cab_a-random-00010", "gt_success": True})  # a top-up: left out
    (folder / "index.jsonl").write_text("".join(json.dumps(e) + "\n" for e in entries))
    (folder / "skipped.jsonl").write_text(json.dumps({"id": "cab_b-random-00003", "sampler": "random", "category": "storage_furniture",
                                                      "instance": -1, "reasons": ["sampler found no action"]}) + "\n")
    (folder / "runs.jsonl").write_text(json.dumps({"stage": "explore", "workers": 2, "trajectories": 15, "skipped": 1,
                                                   "errors": 0, "seconds": 30.0, "load_average": 1.5}) + "\n")
    (folder / "dataset.json").write_text(json.dumps({"rig": "ring5", "per_object": {"random": 10, "grasp": 5}}))


def test_a_dataset_becomes_a_record_and_its_sampler_tables(tmp_path):
    _dataset(tmp_path / "ds")
    record_from_collection(tmp_path / "ds", tmp_path, "pm", command="actaim2 collect --out ds")
    record = load_record(tmp_path, "pm")
    assert record.meta["kind"] == "collection" and record.meta["samples"] == 17
    assert record.meta["seconds"] == 30 and record.meta["load_average"] == 1.5
    assert all("action" not in s and "offset" not in s for s in record.samples)

    rows = {line.split(" | ")[0].strip("| "): line for line in samplers_table([record])[2:]}
    assert "| 2 | 30.0 [10.8-60.3] (3/10) | 50 % | 1 |" in rows["storage_furniture"]
    assert "| 1 | " in rows["table"] and "20.0 [3.6-62.4] (1/5) | 20 % | 0 |" in rows["table"]
    assert "| 3 | 30.0 [10.8-60.3] (3/10) | 50 % | 1 | 20.0 [3.6-62.4] (1/5) | 20 % | 0 |" in rows["all"]

    change = {tuple(c.strip() for c in line.split("|")[1:3]): line for line in dof_change_table([record])[2:]}
    # never touched | touched 0-1 % | 1-5 % | 5-30 % | >= 30 %
    assert change["storage_furniture", "random"].endswith("| 10 | 40 % | 10 % | 0 % | 20 % | 30 % |")
    assert change["table", "grasp"].endswith("| 5 | 80 % | 0 % | 0 % | 0 % | 20 % |")
    assert "actaim2 collect --out ds" in runs_table([record])[2]


def test_the_label_table_scores_the_visual_label_against_the_ground_truth(tmp_path):
    """The cabinets' 3 successes are labelled right, one 10 % move is labelled a success (a
    false positive); the table's one success is missed (a false negative)."""
    _dataset(tmp_path / "ds")
    with pytest.raises(RecordError, match="no visual labels"):
        record_from_collection(tmp_path / "ds", tmp_path, "unlabelled", command="c")
        label_table([load_record(tmp_path, "unlabelled")])
    entries = [json.loads(t) for t in (tmp_path / "ds" / "index.jsonl").read_text().splitlines()]
    false_positive = next(e["id"] for e in entries if e["dof_change"][1] == 0.1)
    visual = [{"id": e["id"], "score": 0.0,
               "success": (e["gt_success"] and e["category"] != "table") or e["id"] == false_positive}
              for e in entries]
    (tmp_path / "ds" / "labels.jsonl").write_text("".join(json.dumps(v) + "\n" for v in visual))
    record_from_collection(tmp_path / "ds", tmp_path, "labelled", command="c")
    rows = {line.split(" | ")[1]: line for line in label_table([load_record(tmp_path, "labelled")])[2:]}
    assert rows["storage_furniture"].startswith("| train_seen (calibration) | storage_furniture | 2 | 11 | 4 |")
    # 11 cabinet trajectories (the top-up counts: the label is judged on all), 1 wrong
    assert "| 90.9 (below) | 92.9 | 80.0 | 100.0 |" in rows["storage_furniture"]
    assert rows["table"].endswith("| 5 | 1 | 80.0 (below) | 50.0 (below) | - | 0.0 |")
