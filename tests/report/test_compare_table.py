"""The `compare` table: ActAIM2 against Data Collection by the protocol's rules, from records
whose answer is known by construction."""
from __future__ import annotations

import pytest

from actaim2.report.records import Record, RecordError
from actaim2.report.tables import compare_table


def _samples(method: str, works: bool) -> list[dict]:
    """Four objects of two categories, 4 groups x 4 repetitions; a working ActAIM2 closes with
    groups 0-1 and opens with 2-3, a failing method never moves anything."""
    out = []
    for k in range(4):
        obj = f"folder:{800 + k}"
        for slot in range(16):
            group = slot % 4
            mode = (["joint_0", -1] if group < 2 else ["joint_0", 1]) if works else None
            out.append({"key": f"{method}|{obj}|{slot}", "method": method, "object": obj, "split": "val",
                        "category": ("table", "faucet")[k % 2], "slot": slot, "reset_seed": slot,
                        "success": works, "group": group, "repetition": slot // 4, "mode": mode})
    return out


def test_a_shared_baseline_record_is_compared_with_each_seeds_record() -> None:
    seeds = [Record(f"s{k}", {}, _samples("actaim2", True)) for k in range(2)]
    baseline = Record("dc", {}, _samples("data_collection", False))
    lines = compare_table([*seeds, baseline])
    assert lines[0] == "**val**"
    exact = "+100.0 [+100.0, +100.0]"
    assert f"| SSR, paired scenes | {exact} | {exact} | yes |" in lines
    assert sum(line.startswith("| 0 |") or line.startswith("| 1 |") for line in lines) == 2  # one row per seed
    reversed_roles = compare_table([Record("s", {}, _samples("actaim2", False)),
                                    Record("dc", {}, _samples("data_collection", False))])
    assert "| SSR, paired scenes | +0.0 [+0.0, +0.0] | +0.0 [+0.0, +0.0] | no |" in reversed_roles
    with pytest.raises(RecordError, match="holds ActAIM2 samples"):
        compare_table([baseline])
