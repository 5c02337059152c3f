"""`bench_predictor` rows: what the lead's `actaim2 bench models` table prints (values are not asserted)."""
from __future__ import annotations

from actaim2.bench.models import bench_predictor, markdown_table
from actaim2.models.predictor import ActionPredictor, PredictorConfig


def test_bench_predictor_rows():
    config = PredictorConfig(embedding_dim=8, image_size=64, patch=16, width=32, layers_within=1, layers_across=1, heads=2)
    rows = bench_predictor(config, threads=1, repeats=2, train_repeats=1, augment_repeats=1)
    assert [r["measure"] for r in rows] == ["forward + 3-D decode", "forward + mode guidance + 3-D decode", "training step",
                                            "per sample (CPU)"]
    assert rows[0]["params"] == ActionPredictor(config).parameter_count() and rows[2]["batch"] == 8
    assert rows[0]["target"] == rows[1]["target"] == "p50 <= 20 ms" and rows[2]["target"] == "p50 <= 300 ms"
    assert rows[3]["target"] == ""
    assert all(r["p50_ms"] > 0 and r["n"] >= 1 for r in rows)
    table = markdown_table(rows).splitlines()
    assert len(table) == 2 + len(rows) and all(line.count("|") == 12 for line in table)
