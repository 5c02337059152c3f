"""What the 2nd mode's group did on half B: the counts behind the 2nd-mode SSR, and what an unselected group scores."""
from __future__ import annotations

from actaim2.eval.tables import SECOND_MODE_OUTCOMES, mode_cells, report, second_mode_table


def record(obj: str, group: int, repetition: int, mode: tuple[str, int] | None) -> dict:
    return {"method": "actaim2", "split": "train_seen", "category": "door", "object": obj, "group": group,
            "repetition": repetition, "success": mode is not None, "mode": list(mode) if mode else None,
            "phases_executed": 4, "note": ""}


CLOSE, OPEN = ("door_joint", -1), ("door_joint", 1)
RECORDS = (
    # door_000: group 0 always closes (1st mode); group 1 opens on half A, opens once and fails once on half B.
    [record("door_000", 0, i, CLOSE) for i in range(4)]
    + [record("door_000", 1, i, m) for i, m in enumerate([OPEN, OPEN, OPEN, None])]
    # door_001: one mode only, so its 2nd mode counts 0 of its per-group half-B count (2).
    + [record("door_001", g, i, CLOSE if i < 2 else None) for g in (0, 1) for i in range(4)]
)


def test_second_mode_table_counts_the_half_b_samples_the_mode_ssr_counts() -> None:
    header, rule, row = second_mode_table(RECORDS, ["actaim2"])
    cells = [c.strip() for c in row.split("|")[1:-1]]
    assert cells[:2] == ["ActAIM2", "Seen objects"]
    counts = dict(zip(SECOND_MODE_OUTCOMES, (int(c.split()[0]) for c in cells[2:-1])))
    assert counts == {"2nd mode": 1, "1st mode": 0, "another mode": 0, "failed": 1, "no 2nd mode on the object": 2}
    second = mode_cells(RECORDS, 2)["actaim2", "train_seen", "AVG", 2]
    assert (second.successes, second.trials) == (counts["2nd mode"], sum(counts.values()))
    # Chance: door_000's half B holds 1 opening in 4 samples, times its chosen group's 2; door_001 none: 0.5 of 4.
    assert cells[-1] == "12.5 %"
    assert header.count("|") == rule.count("|") == row.count("|")
    assert "## What the 2nd mode's group did on half B" in report(RECORDS, ["actaim2"], ["# header"])
