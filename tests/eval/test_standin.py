"""`actaim2 eval-standin`: the three-drawer stand-in on a tiny azure_kinect checkpoint, one placement.

The "after" checkpoint is the tiny one with a fine-tuning lineage written into its JSON (the cluster
tables ``finetune`` would record, made by its own ``cluster_table``); its parent, the "before"
checkpoint, has the same weights. What is checked is the protocol's machinery: the episodes asked,
their verdicts, the report's counts; the tiny policy's skill is not.
"""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from actaim2 import cli
from actaim2.artifact import checkpoint
from actaim2.eval.evalset import EVAL_SEED_BASE
from actaim2.eval.standin import MODES, STATE_NAMES, mode_clusters, plan_episodes, summarise
from actaim2.finetune.clusters import cluster_table
from actaim2.sim.success import SUCCESS_FRACTION
from tiny_checkpoint import make_checkpoint

LABELS = ["push", "push", "pull", "pull"]


def _finetune_lineage(weights_sha256: str) -> dict:
    """lineage.finetune as `actaim2 finetune` writes it, as far as the stand-in reads it: after fine-tuning push and
    pull fall in clusters 0 and 1, before it both in cluster 1."""
    ids = [f"episode_{i}" for i in range(len(LABELS))]
    return {"parent": {"weights_sha256": weights_sha256},
            "before": {"clusters": cluster_table(ids, LABELS, np.array([1, 1, 1, 1]), 2)},
            "after": {"clusters": cluster_table(ids, LABELS, np.array([0, 0, 1, 1]), 2)}}


def test_eval_standin_counts_the_episodes_verdicts(tmp_path):
    before = make_checkpoint(tmp_path / "before", perception="azure_kinect", clusters=2)
    after = tmp_path / "after" / "policy"
    after.parent.mkdir()
    for source in checkpoint.paths(before):
        shutil.copy(source, after.parent / source.name)
    meta = json.loads(checkpoint.paths(after)[1].read_text())
    meta["lineage"]["finetune"] = _finetune_lineage(meta["weights_sha256"])
    checkpoint.paths(after)[1].write_text(json.dumps(meta, indent=2, sort_keys=True))

    out = tmp_path / "standin"
    argv = ["eval-standin", "--before", str(before), "--after", str(after), "--out", str(out), "--quick",
            "--workers", "0", "--no-progress"]
    assert cli.main(argv) == 0
    report = json.loads((out / "standin.json").read_text())
    records = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    # 1 placement x 3 initial states x 2 clusters x 2 checkpoints, all at one reset seed, disjoint from the teleop's
    assert len(records) == report["protocol"]["episodes"] == 12
    assert {r["reset_seed"] for r in records} == set(report["protocol"]["reset_seeds"])
    assert min(report["protocol"]["reset_seeds"]) >= EVAL_SEED_BASE
    assert {(r["method"], r["drawer"], r["requested_cluster"]) for r in records} == \
        {(c, s, k) for c in ("before", "after") for s in STATE_NAMES for k in (0, 1)}
    assert report["conditions"]["after"]["mode_clusters"] == {"push": 0, "pull": 1}
    assert report["conditions"]["before"]["mode_clusters"] == {"push": 1, "pull": 1}
    for r in records:  # each episode started with its drawer half-open, the others shut, and was judged on that drawer
        assert r["initial"][r["dof"]] == pytest.approx(0.5, abs=0.05)
        assert all(v == pytest.approx(0.0, abs=0.05) for dof, v in r["initial"].items() if dof != r["dof"])
        assert r["drawer_moved"] == pytest.approx(r["fractions"][r["dof"]], abs=1e-4)
        assert r["verdicts"] == {m: r["drawer_moved"] * d > SUCCESS_FRACTION for m, d in MODES.items()}
    for condition, result in report["conditions"].items():
        mine = [r for r in records if r["method"] == condition]
        for mode, cluster in result["mode_clusters"].items():
            asked = [r for r in mine if r["requested_cluster"] == cluster]
            assert result["modes"][mode]["all"]["trials"] == 3
            assert result["modes"][mode]["all"]["successes"] == sum(r["verdicts"][mode] for r in asked)
            for state in STATE_NAMES:
                assert result["modes"][mode][state]["successes"] == sum(r["verdicts"][mode] for r in asked if r["drawer"] == state)
        assert result["modes"]["both"]["all"]["trials"] == 6
        for row in result["clusters"]:
            asked = [r for r in mine if r["requested_cluster"] == row["cluster"]]
            assert row["moved"]["trials"] == 3
            assert row["moved"]["successes"] == sum(abs(r["drawer_moved"]) > SUCCESS_FRACTION for r in asked)
            assert (row["push"], row["pull"]) == (sum(r["verdicts"]["push"] for r in asked), sum(r["verdicts"]["pull"] for r in asked))
    text = (out / "standin.md").read_text()
    assert "| all | push |" in text and "| c1 |" in text and "push -> c1, pull -> c1" in text


def _record(condition: str, placement: int, drawer: int, cluster: int, moved: float) -> dict:
    return {"method": condition, "placement": placement, "drawer": STATE_NAMES[drawer], "requested_cluster": cluster,
            "drawer_moved": moved, "verdicts": {m: moved * d > SUCCESS_FRACTION for m, d in MODES.items()}}


def test_summary_counts_each_mode_on_its_cluster_and_each_cluster_either_way():
    moved = {0: -0.45, 1: 0.4, 2: 0.1}  # cluster 0 shuts the drawer, 1 opens it, 2 barely moves it
    records = [_record("after", p, d, c, moved[c] if (p + d) % 2 == 0 else 0.0) for p in range(2) for d in range(3) for c in range(3)]
    summary = summarise(records, {"push": 0, "pull": 1}, 3)
    assert summary["modes"]["push"]["all"].successes == 3 and summary["modes"]["push"]["all"].trials == 6
    assert summary["modes"]["pull"]["middle"].successes == 1 and summary["modes"]["pull"]["middle"].trials == 2
    assert summary["modes"]["both"]["all"].successes == 6 and summary["modes"]["both"]["all"].trials == 12
    assert [(c["moved"].successes, c["push"], c["pull"], c["asked_for"]) for c in summary["clusters"]] == \
        [(3, 3, 0, ["push"]), (3, 0, 3, ["pull"]), (0, 0, 0, [])]
    # one cluster for both modes: its episodes judged twice, each mode by its own direction
    same = summarise(records, {"push": 1, "pull": 1}, 3)
    assert same["modes"]["push"]["all"].successes == 0 and same["modes"]["pull"]["all"].successes == 3
    assert same["clusters"][1]["asked_for"] == ["push", "pull"]


def test_mode_clusters_come_from_the_lineage_only_for_its_own_parent():
    lineage = _finetune_lineage("parent-sha")
    assert mode_clusters("after", lineage, "any", 2, {}) == ({"push": 0, "pull": 1}, "push: lineage.finetune.after.clusters.label_cluster; "
                                                                                        "pull: lineage.finetune.after.clusters.label_cluster")
    assert mode_clusters("before", lineage, "parent-sha", 2, {})[0] == {"push": 1, "pull": 1}
    with pytest.raises(ValueError, match="parent has weights parent-sha"):
        mode_clusters("before", lineage, "another-sha", 2, {})
    assert mode_clusters("before", lineage, "another-sha", 2, {"push": 0, "pull": 1})[0] == {"push": 0, "pull": 1}
    with pytest.raises(ValueError, match="not one of the checkpoint's 2"):
        mode_clusters("after", lineage, "any", 2, {"pull": 5})
    with pytest.raises(ValueError, match="give --push-cluster"):
        mode_clusters("before", None, "any", 2, {"pull": 0})
    # fine-tuned by mode label: the map it was trained with, the one /sample_mode serves labels by
    labelled = {**lineage, "mode_labels": {"label_cluster": {"push": 1, "pull": 0}}}
    assert mode_clusters("after", labelled, "any", 2, {}) == ({"push": 1, "pull": 0}, "push: lineage.finetune.mode_labels.label_cluster; "
                                                                                         "pull: lineage.finetune.mode_labels.label_cluster")


def test_a_placement_is_one_seed_for_its_states_clusters_and_checkpoints():
    episodes = plan_episodes({"before": [0, 1], "after": [0, 1]}, {"before": 2, "after": 2}, 3)
    assert len(episodes) == 3 * 3 * 2 * 2 and len({e.key for e in episodes}) == len(episodes)
    seeds = {p: {e.reset_seed for e in episodes if e.placement == p} for p in range(3)}
    assert all(len(s) == 1 for s in seeds.values()) and len(set.union(*seeds.values())) == 3
    assert all(e.dof_fraction == [0.5 if i == e.drawer else 0.0 for i in range(3)] for e in episodes)
