"""`actaim2 evaluate` end to end on tiny real checkpoints: --smoke with every policy row, and resuming after a kill.

The checkpoints are trained in this test (tiny_checkpoint.py, seconds); the evaluation runs as
the user runs it, a separate `actaim2 evaluate` process with worker processes, the simulator
rendering with SAPIEN (lavapipe) or, without a Vulkan device, by ray casting (--allow-raycast).
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from actaim2.artifact.serving import DEFAULT_SERVING
from actaim2.eval.methods import PSEUDO_GROUPING
from tiny_checkpoint import CLUSTERS, make_checkpoint, make_encoder

SMOKE_OBJECTS = 3  # presets.PRESETS["smoke"]: storage_furniture 0 and 8, box 0


@pytest.fixture(scope="module")
def checkpoints(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("checkpoints")
    out = {kind: make_checkpoint(root / kind, kind) for kind in ("cgmvae", "vqvae", "cvae")}
    out["encoder"] = make_encoder(root / "encoder.pt")
    return out


def evaluate(*args: str) -> list[str]:
    return [sys.executable, "-m", "actaim2.cli", "evaluate", "--no-progress", "--allow-raycast", *map(str, args)]


def records(out: Path) -> list[dict]:
    path = out / "results.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def run_until(command: list[str], out: Path, n: int) -> None:
    """Start ``command`` and SIGKILL it (and its workers) once ``n`` samples are in the results."""
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.monotonic() + 600
    while len(records(out)) < n and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.2)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()


@pytest.mark.timeout(1200)
def test_smoke_interrupted_and_resumed(checkpoints, tmp_path) -> None:
    """--smoke with every policy row: killed after a few samples, the same command finishes the rest
    without redoing one, and writes the tables."""
    out = tmp_path / "smoke"
    command = evaluate("--smoke", "--out", out, "--checkpoint", checkpoints["cgmvae"], "--vqvae", checkpoints["vqvae"],
                       "--cvae", checkpoints["cvae"], "--encoder", checkpoints["encoder"], "--workers", 2, "--figures", 1)
    per_object = {"actaim2": CLUSTERS, "vqvae_rvt": CLUSTERS, "actaim_cvae": 2, "goal_rvt": 2, "random": 2}
    planned = SMOKE_OBJECTS * sum(per_object.values())
    started = time.monotonic()
    run_until(command, out, 3)
    before = (out / "results.jsonl").read_text()
    done = [r["key"] for r in records(out)]
    assert 3 <= len(done) < planned, f"{len(done)} records before the kill"
    with open(out / "results.jsonl", "a") as f:
        f.write('{"key": "cut sho')  # a line a kill cut short is dropped on resume
    result = subprocess.run(command, capture_output=True, text=True, timeout=900)
    print(f"--smoke, killed and resumed: {time.monotonic() - started:.0f} s (load average {os.getloadavg()[0]:.1f})")
    assert result.returncode == 0, result.stdout + result.stderr
    assert f"{len(done)} already done" in result.stdout
    assert (out / "results.jsonl").read_text().startswith(before)  # the first records untouched
    rows = records(out)
    keys = [r["key"] for r in rows]
    assert len(keys) == len(set(keys)) == planned and keys[: len(done)] == done
    assert {m: sum(r["method"] == m for r in rows) for m in per_object} == {m: n * SMOKE_OBJECTS for m, n in per_object.items()}
    assert {r["split"] for r in rows} == {"train_seen", "train_unseen_instance", "heldout_category"}
    for r in rows:
        assert r["reset_seed"] >= 2**31  # disjoint from every collection seed
        assert 0 <= r["phases_executed"] <= 4 and isinstance(r["success"], bool)
        assert r["success"] == (r["largest_change"] > 0.3)
    assert sorted({r["cluster"] for r in rows if r["method"] == "actaim2"}) == list(range(CLUSTERS))  # asked for each
    assert all(r["cluster"] == -1 for r in rows if r["method"] == "actaim_cvae")
    assert all(r["goal"][1] in (1, -1) for r in rows if r["method"] == "goal_rvt" and "goal" in r)
    seeds: dict = {}  # the same scenes for every row: slot s of an object has one reset seed whatever the method
    for r in rows:
        assert seeds.setdefault((r["object"], r["slot"]), r["reset_seed"]) == r["reset_seed"]
    tables = (out / "tables.md").read_text()
    for text in ("Command: `actaim2 evaluate", "weights sha256", "## Table 1", "**Seen objects**", "**Unseen instances**",
                 "**Unseen categories**", "| ActAIM2 |", "| VQVAE-RVT |", "| ActAIM (CVAE) |", "| Goal-RVT (oracle) |",
                 "| Random sampler |", "## Table 2", "## Acceptance checks", "## Where samples stopped", "Where2Act", "## Figures"):
        assert text in tables, text
    for name in ("embeddings_storage_furniture_000.png", "heatmaps_storage_furniture_000.png"):  # --figures 1
        assert (out / "figures" / name).stat().st_size > 1000 and f"(figures/{name})" in tables

    # Re-running 4 of its samples by their seeds (what the protocol asks of 40 test samples).
    again = tmp_path / "again"
    rerun = [again if a == str(out) else a for a in command] + ["--reproduce", str(out), "--reproduce-samples", "4",
                                                                "--figures", "0"]
    result = subprocess.run(rerun, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stdout + result.stderr
    reproduction = json.loads((again / "reproduction.json").read_text())
    rerun_rows = records(again)
    assert reproduction["samples"] == 4 == len(rerun_rows) and {r["key"] for r in rerun_rows} <= set(keys)
    assert reproduction["same"] + len(reproduction["differ"]) == 4 and reproduction["same"] >= 3, reproduction
    assert f"reproduced {reproduction['same']} of 4 outcomes" in result.stdout
    empty = tmp_path / "empty"
    empty.mkdir()
    refused = subprocess.run([again if a == str(out) else a for a in command] + ["--reproduce", str(empty)],
                             capture_output=True, text=True, timeout=300)
    assert refused.returncode == 2 and "holds neither results.jsonl" in refused.stderr


def test_other_checkpoint_refused(checkpoints, tmp_path) -> None:
    """Results of two checkpoints for one row never mix: resuming with another is refused, naming both."""
    out = tmp_path / "mix"
    out.mkdir()
    (out / "run.json").write_text(json.dumps({"eval_set_version": 1, "robot": "panda", "rig": "ring5",
                                              "hand_half_turn": True, "pseudo_grouping": PSEUDO_GROUPING,
                                              "keypose_alternatives": DEFAULT_SERVING.keypose_alternatives, "noise_scale": DEFAULT_SERVING.noise_scale,
                                              "methods": {"actaim2": "0" * 64}}))
    result = subprocess.run(evaluate("--smoke", "--out", out, "--checkpoint", checkpoints["cgmvae"], "--methods", "actaim2"),
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and "actaim2 results made with " + "0" * 64 in result.stderr


@pytest.mark.parametrize("recorded, flags", [(False, ()), (True, ("--no-hand-half-turn",))])
def test_other_planner_refused(checkpoints, tmp_path, recorded: bool, flags: tuple[str, ...]) -> None:
    """Results planned with and without the hand's half turn never mix either: the default (on) against a run
    made without it, and --no-hand-half-turn against one made with it."""
    out = tmp_path / "planner"
    out.mkdir()
    (out / "run.json").write_text(json.dumps({"eval_set_version": 1, "robot": "panda", "rig": "ring5",
                                              "hand_half_turn": recorded, "methods": {}}))
    result = subprocess.run(evaluate("--smoke", "--out", out, "--checkpoint", checkpoints["cgmvae"], "--methods", "actaim2",
                                     *flags), capture_output=True, text=True, timeout=300)
    message = (f"hand_half_turn {recorded}, this run has {not recorded}: use another --out "
               f"(or {'--hand-half-turn' if recorded else '--no-hand-half-turn'} to resume it)")
    assert result.returncode == 2 and message in result.stderr, result.stderr


def test_other_number_of_fallbacks_refused(checkpoints, tmp_path) -> None:
    """Results with and without fallback keyposes never mix: a run made with 2 (run.json), resumed with none."""
    out = tmp_path / "fallbacks"
    out.mkdir()
    (out / "run.json").write_text(json.dumps({"eval_set_version": 1, "robot": "panda", "rig": "ring5", "hand_half_turn": True,
                                              "pseudo_grouping": PSEUDO_GROUPING, "keypose_alternatives": 2, "methods": {}}))
    result = subprocess.run(evaluate("--smoke", "--out", out, "--checkpoint", checkpoints["cgmvae"], "--methods", "actaim2",
                                     "--keypose-alternatives", 0), capture_output=True, text=True, timeout=300)
    message = "keypose_alternatives 2, this run has 0: use another --out (or --keypose-alternatives 2 to resume it)"
    assert result.returncode == 2 and message in result.stderr, result.stderr


@pytest.mark.timeout(900)
def test_ablation_row_refuses_a_checkpoint_that_is_not_its_ablation(checkpoints, tmp_path) -> None:
    """--ablation-depth given a full policy: refused before any sample, saying why (each row's rule: test_ablation_rows.py)."""
    result = subprocess.run(evaluate("--smoke", "--out", tmp_path / "ablation", "--ablation-depth", checkpoints["cgmvae"],
                                     "--ablation-single-view", checkpoints["cgmvae"]), capture_output=True, text=True, timeout=600)
    assert result.returncode == 2 and "actaim2_depth: checkpoint" in result.stderr, result.stderr
    assert "the depth-only row needs depth without rgb and xyz" in result.stderr


@pytest.mark.timeout(900)
def test_grounding_experiment(checkpoints, tmp_path) -> None:
    """--grounding: bandit (ActAIM2) and CEM (CVAE, VQ-VAE) runs for both targets, the plot, resumable by run."""
    out = tmp_path / "grounding"
    command = evaluate("--out", out, "--checkpoint", checkpoints["cgmvae"], "--cvae", checkpoints["cvae"], "--vqvae",
                       checkpoints["vqvae"], "--grounding", "table:0", "--grounding-iterations", 2, "--grounding-seeds", 1,
                       "--workers", 0)
    result = subprocess.run(command, capture_output=True, text=True, timeout=800)
    assert result.returncode == 0, result.stdout + result.stderr
    runs = [json.loads(line) for line in (out / "grounding" / "results.jsonl").read_text().splitlines()]
    assert sorted((r["method"], r["target"]) for r in runs) == sorted(
        (m, t) for m in ("actaim2", "actaim_cvae", "vqvae_rvt") for t in (1, -1))
    for r in runs:
        assert len(r["rewards"]) == 2 and set(r["rewards"]) <= {0, 1} and r["dof"]
        if r["method"] == "actaim2":
            assert all(0 <= c < CLUSTERS for c in r["choices"])  # the bandit's arms are the clusters
    assert (out / "figures" / "grounding.png").stat().st_size > 1000
    assert "| actaim2 | Thompson bandit over clusters | open | 1 |" in (out / "grounding.md").read_text()
    again = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0 and "6 already done" in again.stdout
