"""The input-ablation rows of the evaluation: planned exactly as the ActAIM2 row, and checked against their checkpoint."""
from __future__ import annotations

from actaim2.eval.evalset import catalogue_objects
from actaim2.eval.methods import ABLATIONS, ablation_problem
from actaim2.eval.presets import PRESETS
from actaim2.eval.tasks import plan_tasks


def test_ablation_rows_get_actaim2s_samples_per_cluster_on_the_same_slots():
    objects = catalogue_objects(("train_seen",), 1, ("storage_furniture",))
    counts = PRESETS["full"].counts
    tasks = plan_tasks({"actaim2": 8, **{m: 8 for m in ABLATIONS}, "actaim_cvae": 0}, objects, counts)
    slots = {m: sorted((t.obj.key, t.slot, t.cluster) for t in tasks if t.method == m) for m in ("actaim2", *ABLATIONS)}
    assert len(slots["actaim2"]) == counts.per_cluster * 8 * len(objects)
    assert all(slots[m] == slots["actaim2"] for m in ABLATIONS)
    assert sum(t.method == "actaim_cvae" for t in tasks) == counts.per_object * len(objects)


def test_an_ablation_row_takes_only_a_predictor_that_reads_what_it_names():
    assert ablation_problem("actaim2_depth", ["depth", "uv"], "all") is None
    assert ablation_problem("actaim2_depth", ["depth"], "all") is None
    assert "rgb and xyz" in ablation_problem("actaim2_depth", ["rgb", "depth", "uv"], "all")
    assert "rgb and xyz" in ablation_problem("actaim2_depth", ["depth", "uv"], "back")
    assert ablation_problem("actaim2_single_view", ["rgb", "xyz", "depth", "uv"], "back") is None
    assert "all five views" in ablation_problem("actaim2_single_view", ["rgb", "xyz", "depth", "uv"], "all")
