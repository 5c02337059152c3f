"""Results with and without mode guidance never mix (eval/results.py's run.json), and the flag is checked."""
from __future__ import annotations

import json
import subprocess

import pytest

from actaim2.eval.methods import PSEUDO_GROUPING
from actaim2.eval.results import RunMismatchError, check_run

RUN = {"eval_set_version": 1, "robot": "panda", "rig": "ring5", "hand_half_turn": True, "pseudo_grouping": PSEUDO_GROUPING,
       "keypose_alternatives": 4, "methods": {"random": "random"}}


def test_a_run_with_another_guidance_weight_is_refused_naming_the_flag(tmp_path):
    check_run(tmp_path, {**RUN, "mode_guidance": 2.0})
    with pytest.raises(RunMismatchError, match=r"mode_guidance 2.0, this run has 0.0: use another --out "
                                                r"\(or --mode-guidance 2.0 to resume it\)"):
        check_run(tmp_path, {**RUN, "mode_guidance": 0.0})
    assert check_run(tmp_path, {**RUN, "mode_guidance": 2.0})["mode_guidance"] == 2.0


def test_a_run_json_from_before_the_field_is_a_run_without_guidance(tmp_path):
    (tmp_path / "run.json").write_text(json.dumps(RUN))
    assert check_run(tmp_path, {**RUN, "mode_guidance": 0.0})["mode_guidance"] == 0.0
    with pytest.raises(RunMismatchError, match="mode_guidance 0.0, this run has 1.5"):
        check_run(tmp_path, {**RUN, "mode_guidance": 1.5})


def test_a_negative_weight_is_refused_before_any_sample(tmp_path):
    result = subprocess.run(["actaim2", "evaluate", "--smoke", "--out", str(tmp_path / "out"), "--methods", "random",
                             "--mode-guidance", "-1"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and "--mode-guidance -1.0 is not a weight >= 0" in result.stderr, result.stderr
    assert not (tmp_path / "out").exists()
