"""An earlier revision's code beside today's (bench/baseline.py) and the throughput summary."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

from actaim2.bench.baseline import export_tree, modules_at, python_path
from actaim2.bench.throughput import OTHER, summary
from actaim2.perception import cloud_codec, fusion
from actaim2.profiling import Profile


def test_modules_of_a_revision_load_beside_todays_and_see_each_other():
    old = modules_at("HEAD", ["actaim2.perception.cloud_codec", "actaim2.perception.fusion"])
    codec, old_fusion = old["actaim2.perception.cloud_codec"], old["actaim2.perception.fusion"]
    assert codec is not cloud_codec and old_fusion is not fusion
    assert sys.modules["actaim2.perception.fusion"] is fusion  # today's stays in place
    wire = codec.encode(np.arange(12, dtype=np.float32).reshape(2, 2, 3))
    decoded = codec.decode(wire.fields, wire.data, wire.height, wire.width, wire.point_step,
                           wire.row_step)
    np.testing.assert_array_equal(decoded.xyz, np.arange(12).reshape(4, 3))
    assert old_fusion.CameraCloud is not fusion.CameraCloud


def test_an_exported_tree_is_imported_before_todays(tmp_path):
    tree = export_tree("HEAD", tmp_path)
    command = [sys.executable, "-c", "import actaim2.profiling as m; print(m.__file__)"]
    env = dict(os.environ, PYTHONPATH=python_path(tree))
    shown = subprocess.run(command, env=env, capture_output=True, text=True)
    assert shown.returncode == 0, shown.stderr
    assert shown.stdout.strip() == str(tree / "src" / "actaim2" / "profiling.py")


def test_the_summary_gives_the_untimed_rest_its_own_row():
    runs = []
    for seconds in (1.0, 3.0):
        profile = Profile()
        profile.seconds, profile.calls = {"physics": seconds / 2}, {"physics": 10}
        runs.append((profile, seconds))
    wall, rows = summary(runs)
    assert wall == 2000.0 and rows["physics"] == (1000.0, 10.0)
    assert rows[OTHER][0] == 1000.0
