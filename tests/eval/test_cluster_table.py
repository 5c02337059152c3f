"""SSR per cluster: each cluster's rate and the share of its samples that ran all four phases."""
from __future__ import annotations

from actaim2.eval.tables import cluster_table, report


def record(method: str, group: int, success: bool, phases: int = 4, split: str = "train_seen") -> dict:
    return {"method": method, "split": split, "category": "faucet", "object": "faucet_000", "group": group,
            "repetition": 0, "success": success, "phases_executed": phases, "mode": None, "note": ""}


RECORDS = [
    record("actaim2", 0, True), record("actaim2", 0, False, phases=1), record("actaim2", 1, False),
    record("actaim2", 1, False), record("actaim2", 1, True, split="train_unseen_instance"),
    record("data_collection", 5, True),  # pseudo-clusters are not clusters: no row
]


def cells(line: str) -> list[str]:
    return [c.strip() for c in line.split("|")[1:-1]]


def test_cluster_table_gives_each_clusters_ssr_and_share_that_ran() -> None:
    header, rule, seen, unseen = cluster_table(RECORDS, ["actaim2", "data_collection"])
    assert cells(header) == ["method", "split", "cluster 0", "cluster 1", "samples"]
    assert header.count("|") == rule.count("|")
    row = cells(seen)
    assert row[:2] == ["ActAIM2", "Seen objects"] and row[-1] == "4"
    assert row[2].startswith("50.0 [") and row[2].endswith("/ 50 %")
    assert row[3].startswith("0.0 [") and row[3].endswith("/ 100 %")
    row = cells(unseen)
    assert row[1] == "Unseen instances" and row[2] == "-" and row[3].startswith("100.0 [")


def test_cluster_table_without_clustered_rows_says_so() -> None:
    assert cluster_table(RECORDS[-1:], ["data_collection"]) == ["(no row sampled by cluster)"]
    assert "## SSR per cluster" in report(RECORDS, ["actaim2", "data_collection"], ["# header"])
