"""Paired comparison of two evaluation runs: exact McNemar p-values, pairing checks, `actaim2 eval-compare`."""
from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from actaim2.cli import main as cli_main
from actaim2.eval.paired import AVG, UnpairedError, mcnemar_exact, pair_records, paired_cells


def exact_two_sided(k: int, n: int) -> float:
    """The binomial two-sided p at 1/2 by its definition: twice the smaller tail, at most 1."""
    tail = sum(math.comb(n, i) for i in range(min(k, n - k) + 1)) / 2 ** n
    return min(1.0, 2 * tail)


@pytest.mark.parametrize("only_a, only_b", [(1, 9), (9, 1), (164, 133), (5, 5), (0, 7), (3, 0)])
def test_mcnemar_exact_is_the_two_sided_binomial_test_of_the_discordant_samples(only_a: int, only_b: int) -> None:
    assert mcnemar_exact(only_a, only_b) == pytest.approx(exact_two_sided(only_a, only_a + only_b), rel=1e-9)


def test_mcnemar_exact_edge_cases() -> None:
    assert mcnemar_exact(0, 0) == 1.0
    assert mcnemar_exact(1, 9) == pytest.approx(22 / 1024)  # 2 * (1 + 10) / 2^10
    assert mcnemar_exact(164, 133) == pytest.approx(0.0816, abs=5e-4)  # docs/evaluation.md's blurred decode: 0.08
    with pytest.raises(ValueError, match=">= 0"):
        mcnemar_exact(-1, 3)


def record(obj: str, slot: int, success: bool, phases: int = 4, category: str = "table", split: str = "train_seen",
           method: str = "actaim2", seed: int = 0) -> dict:
    return {"key": f"{method}|{obj}|{slot}", "method": method, "split": split, "category": category, "object": obj,
            "slot": slot, "reset_seed": 1000 + slot + seed, "sample_seed": 2000 + slot, "requested_cluster": slot % 8,
            "success": success, "phases_executed": phases}


def by_key(records: list[dict]) -> dict[str, dict]:
    return {r["key"]: r for r in records}


# run A: table_000 slots 0-5 and door_000 slots 0-3; run B the same samples, some outcomes flipped,
# plus one key A lacks (an unfinished or extra sample is not counted)
A = [record("table_000", 0, True), record("table_000", 1, True), record("table_000", 2, False, 1),
     record("table_000", 3, False, 0), record("table_000", 4, True), record("table_000", 5, False),
     record("door_000", 0, False, 1, "door"), record("door_000", 1, False, 2, "door"),
     record("door_000", 2, True, 4, "door"), record("door_000", 3, False, 4, "door")]
B = [record("table_000", 0, True), record("table_000", 1, False), record("table_000", 2, True),
     record("table_000", 3, True), record("table_000", 4, True), record("table_000", 5, False),
     record("door_000", 0, True, 4, "door"), record("door_000", 1, False, 4, "door"),
     record("door_000", 2, True, 4, "door"), record("door_000", 3, False, 4, "door"),
     record("door_000", 4, True, 4, "door")]


def test_paired_cells_count_the_two_by_two_table_per_category_and_split() -> None:
    cells = paired_cells(pair_records(by_key(A), by_key(B)))
    table, door, avg = (cells["actaim2", "train_seen", c] for c in ("table", "door", AVG))
    assert (table.both, table.only_a, table.only_b, table.neither) == (2, 1, 2, 1)
    assert (door.both, door.only_a, door.only_b, door.neither) == (1, 0, 1, 2)
    assert avg == table + door and avg.samples == 10
    assert (avg.rate_a.successes, avg.rate_b.successes) == (4, 6)
    assert (avg.ran_a, avg.ran_b) == (6, 10)
    assert avg.p_value == pytest.approx(exact_two_sided(1, 4))


def test_pairing_refuses_runs_without_a_common_sample_or_with_other_samples_under_one_key() -> None:
    with pytest.raises(UnpairedError, match="share no sample"):
        pair_records(by_key(A), by_key([record("safe_000", 0, True, category="safe")]))
    other_seeds = [record(r["object"], r["slot"], r["success"], category=r["category"], seed=7) for r in B]
    with pytest.raises(UnpairedError, match="reset_seed"):
        pair_records(by_key(A), by_key(other_seeds))


def write_run(folder: Path, records: list[dict], hand_half_turn: bool) -> None:
    folder.mkdir()
    (folder / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    (folder / "run.json").write_text(json.dumps({"eval_set_version": 1, "hand_half_turn": hand_half_turn, "rig": "ring5",
                                                 "robot": "panda", "methods": {"actaim2": "ab12"}}))


def test_eval_compare_writes_the_paired_table_and_names_what_differs(tmp_path: Path, capsys) -> None:
    write_run(tmp_path / "a", A, False)
    write_run(tmp_path / "b", B, True)
    out = tmp_path / "compare.md"
    assert cli_main(["eval-compare", str(tmp_path / "a"), str(tmp_path / "b"), "--out", str(out)]) == 0
    text = out.read_text()
    assert text == capsys.readouterr().out
    assert "hand_half_turn: False -> True" in text and "checkpoint of actaim2" not in text
    assert "10 samples in both; 0 only in A, 1 only in B" in text
    avg = next(line for line in text.splitlines() if "**AVG**" in line)
    cells = [c.strip() for c in avg.split("|")[1:-1]]
    assert cells[:4] == ["ActAIM2", "Seen objects", "**AVG**", "10"]
    assert cells[4].startswith("40.0 [") and cells[5].startswith("60.0 [")
    assert cells[6:9] == ["1", "3", f"{exact_two_sided(1, 4):.3g}"] and cells[9] == "60.0 % / 100.0 %"


def test_eval_compare_says_what_is_wrong_with_its_input(tmp_path: Path, capsys) -> None:
    write_run(tmp_path / "a", A, False)
    assert cli_main(["eval-compare", str(tmp_path / "a"), str(tmp_path / "missing")]) == 2
    assert "holds no evaluation" in capsys.readouterr().err
    write_run(tmp_path / "c", [record("safe_000", 0, True, category="safe")], False)
    assert cli_main(["eval-compare", str(tmp_path / "a"), str(tmp_path / "c")]) == 2
    assert "share no sample" in capsys.readouterr().err
