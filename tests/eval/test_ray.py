"""`actaim2 evaluate --ray local`: the same samples on Ray actors (a private local Ray instance,
on loopback only, as the project's DDS is)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from actaim2.parallel import ray_available

SMOKE_OBJECTS = 3


@pytest.mark.skipif(ray_available() is not None, reason=str(ray_available()))
@pytest.mark.timeout(900)
def test_ray_local_instance(tmp_path) -> None:
    out = tmp_path / "ray"
    result = subprocess.run([sys.executable, "-m", "actaim2.cli", "evaluate", "--smoke", "--methods", "random", "--out", str(out),
                             "--ray", "local", "--workers", "1", "--no-progress", "--allow-raycast"],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "Ray: a local instance at 127.0.0.1:" in result.stdout and "(loopback only)" in result.stdout, result.stdout
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert sorted(r["key"] for r in rows) == sorted(f"random|{o}|{s}" for o in ("storage_furniture_000", "storage_furniture_008",
                                                                               "box_000") for s in range(2))
    assert all("success" in r and r["phases_executed"] >= 0 for r in rows)
    assert "(Ray local)" in (out / "tables.md").read_text()
