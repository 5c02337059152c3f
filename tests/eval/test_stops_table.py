"""Where samples stopped: each record's phase and reason read from its note, shares and the SSR of complete samples."""
from __future__ import annotations

from actaim2.eval.tables import stop_of, stops_table


def record(phases: int, note: str = "", success: bool = False, method: str = "actaim2") -> dict:
    return {"method": method, "phases_executed": phases, "note": note, "success": success}


RECORDS = [
    {**record(4, success=True), "candidate": [0, 2, 0, 0]},  # REACH ran its second fallback
    {**record(4), "candidate": [0, 0, 0, 0]},
    record(1, "REACH: environment_collision: IK for [0.7, 0.0, 0.4]: environment_collision: every solution collides"),
    record(0, "INIT: environment_collision: INIT: environment collision between panda_hand_0 and point cloud"),
    record(3, "MANIPULATE: straight_line: MANIPULATE: straight line refused: at 40% of the 200 mm line", success=True),
    record(0, "no sample: sampler found no action", method="data_collection"),
    record(4, success=True, method="data_collection"),
]


def test_stop_of_reads_phase_and_reason() -> None:
    assert [stop_of(r) for r in RECORDS] == [("", ""), ("", ""), ("REACH", "environment_collision"),
                                            ("INIT", "environment_collision"), ("MANIPULATE", "straight_line"),
                                            ("no sample", ""), ("", "")]


def test_stops_table_shares_and_ssr_of_samples_that_ran_all_four_phases() -> None:
    header, rule, actaim2, data_collection = stops_table(RECORDS, ["actaim2", "data_collection", "random"])
    assert header.count("|") == rule.count("|")
    cells = [c.strip() for c in actaim2.split("|")[1:-1]]
    # samples, no sample, INIT, REACH, GRASP, MANIPULATE, all four ran, their SSR (1 of 2), reasons
    assert cells[:8] == ["ActAIM2", "5", "0.0 %", "20.0 %", "20.0 %", "0.0 %", "20.0 %", "40.0 %"]
    assert cells[8].startswith("50.0 [")  # a part moved by a refused MANIPULATE counts for SSR, not here
    assert cells[9] == "20.0 %"  # one of five ran a fallback (records without candidates: none)
    assert "REACH environment_collision 20.0 %" in cells[10] and "MANIPULATE straight_line 20.0 %" in cells[10]
    cells = [c.strip() for c in data_collection.split("|")[1:-1]]
    assert cells[1:3] == ["2", "50.0 %"] and cells[7] == "50.0 %" and cells[8].startswith("100.0 [")
