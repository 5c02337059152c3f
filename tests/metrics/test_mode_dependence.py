"""The permutation test of group against outcome, on synthetic evaluations whose answer is known."""
from __future__ import annotations

import numpy as np
from sklearn.metrics import mutual_info_score

from actaim2.eval.tables import report
from actaim2.metrics.mode_dependence import dependence, dependence_cells, mutual_information

OUTCOMES = (["drawer", 1], ["drawer", -1], None)  # open, close, failure


def records(rng: np.random.Generator, objects: int, select: float, method: str = "actaim2") -> list[dict]:
    """8 groups x 4 samples per object; with probability ``select`` a sample's outcome is its group's
    own (group % 3), otherwise drawn at random."""
    out = []
    for o in range(objects):
        for group in range(8):
            for repetition in range(4):
                kind = group % 3 if rng.random() < select else int(rng.integers(3))
                out.append({"method": method, "split": "train_seen", "category": "storage_furniture", "object": f"o{o}",
                            "group": group, "repetition": repetition, "success": kind < 2, "mode": OUTCOMES[kind],
                            "phases_executed": 4, "note": ""})
    return out


def test_mutual_information_is_sklearns_for_every_row():
    rng = np.random.default_rng(0)
    outcomes = rng.integers(0, 3, 40)
    groups = np.stack([rng.integers(0, 8, 40) for _ in range(5)])
    expected = [mutual_info_score(g, outcomes) for g in groups]
    np.testing.assert_allclose(mutual_information(groups, outcomes), expected, atol=1e-12)


def test_groups_that_select_outcomes_are_detected():
    cell = dependence_cells(records(np.random.default_rng(1), objects=12, select=0.4))["actaim2", "train_seen"]
    assert (cell.objects, cell.samples) == (12, 384)
    assert cell.mutual_information > cell.shuffled_mean and cell.p_value < 0.01


def test_groups_that_select_nothing_are_not_and_their_p_values_are_uniform():
    p = [dependence_cells(records(np.random.default_rng(seed), objects=6, select=0.0))["actaim2", "train_seen"].p_value
         for seed in range(40)]
    assert 0.35 < np.mean(p) < 0.65  # uniform on [0, 1] has mean 0.5 (40 draws: standard error 0.046)
    assert sum(v < 0.05 for v in p) <= 5  # 2 expected


def test_a_single_outcome_carries_no_information():
    groups, outcomes = np.arange(32) % 8, np.zeros(32, np.int64)
    cell = dependence([(groups, outcomes)], permutations=50)
    assert cell.mutual_information == 0.0 and cell.p_value == 1.0


def test_the_report_has_the_table():
    text = report(records(np.random.default_rng(2), objects=3, select=1.0), ["actaim2"], ["# test"])
    section = text.split("## Do the groups select outcomes?")[1].split("##")[0]
    assert "| ActAIM2 | " in section and "p 0.002" in section  # 1 / (1 + 500): no permutation reached it


def test_a_row_with_one_sample_per_group_has_no_mode_tables():
    """The random sampler at 8 per object: one sample per pseudo-cluster, so no half B to measure a
    mode on and an MI that every permutation ties; it is named, not shown as empty rows or p 1.000."""
    once = [r for r in records(np.random.default_rng(3), objects=3, select=0.0, method="random") if r["repetition"] == 0]
    text = report(records(np.random.default_rng(2), objects=3, select=1.0) + once, ["actaim2", "random"], ["# test"])
    table1, rest = text.split("## Table 2")
    assert "| Random sampler | " in table1  # its SSR stays
    modes = rest.split("## SSR per cluster")[0]
    assert "Without Mode SSR (one sample per group): Random sampler." in modes
    assert "| Random sampler" not in modes and "| ActAIM2, 1st mode | " in modes and "| ActAIM2 | " in modes
