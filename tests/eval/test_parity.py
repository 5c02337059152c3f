"""`actaim2 parity` end to end on a tiny real checkpoint, 2 of the 20 tuples: the library evaluation and the
ROS loop (sim_node, fusion_node, policy_node, control_node and episode_runner, each its own process, over
real DDS) both run every tuple and the report shows both outcomes."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest

from tiny_checkpoint import make_checkpoint


@pytest.mark.timeout(900)
def test_parity_runs_both_paths_and_reports_both_outcomes(tmp_path) -> None:
    stem = make_checkpoint(tmp_path / "policy")
    out = tmp_path / "parity"
    started = time.monotonic()
    result = subprocess.run([sys.executable, "-m", "actaim2.cli", "parity", "--checkpoint", str(stem), "--out", str(out),
                             "--tuples", "2", "--allow-raycast", "--domain-id", os.environ["ROS_DOMAIN_ID"]],
                            capture_output=True, text=True, timeout=840)
    print(f"parity, 2 tuples: {time.monotonic() - started:.0f} s (load average {os.getloadavg()[0]:.1f})")
    logs = "\n".join(f"--- {p.name}\n{p.read_text(errors='replace')[-1500:]}" for p in sorted((out / "logs").glob("*.log")))
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:] + logs
    rows = [json.loads(line) for line in (out / "parity.jsonl").read_text().splitlines()]
    assert [(r["object"], r["cluster"]) for r in rows] == [("faucet_000", 0), ("table_000", 1)]
    for row in rows:
        assert row["seed"] >= 2**31  # an evaluation scene, never a training one
        library, ros = row["library"], row["ros"]
        assert isinstance(library["success"], bool) and isinstance(ros["success"], bool), row
        assert library["cluster"] == ros["cluster"] == row["cluster"]  # the same mode asked both ways
        assert ros["object_id"] == row["object"]  # the same object loaded both ways
        assert library["success"] == (library["largest_change"] > 0.3) and ros["success"] == (ros["largest_change"] > 0.3)
        # The tiny checkpoint's keyposes are reachable on both objects: each path executed the whole episode.
        assert library["phases_executed"] == ros["phases_executed"] == 4, row
    agree = sum(r["library"]["success"] == r["ros"]["success"] for r in rows)
    report = (out / "parity.md").read_text()
    assert f"**Agreement: {agree} / 2**" in report
    assert report.count("| faucet_000 |") == 1 and report.count("| table_000 |") == 1
    # Both simulated controller and control_node ran with goal tolerances off (0), as the library's executor.
    assert "goal tolerances: not checked on sim_node and control_node" in report
