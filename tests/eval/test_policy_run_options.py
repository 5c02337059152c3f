"""Results made with another mode guidance weight or noise scale never mix (eval/results.py's run.json), and both
flags are checked before any sample."""
from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

from actaim2.eval.methods import PSEUDO_GROUPING
from actaim2.eval.results import RunMismatchError, check_run
from actaim2.eval.sources import PolicySource
from actaim2.perception.config import load_perception_config
from actaim2.policy.inference import PolicyModel
from actaim2.policy.views import Views
from actaim2.robots import load_robot_spec
from tiny_checkpoint import RESOLUTION, make_checkpoint

RUN = {"eval_set_version": 1, "robot": "panda", "rig": "ring5", "hand_half_turn": True, "pseudo_grouping": PSEUDO_GROUPING,
       "keypose_alternatives": 4, "methods": {"random": "random"}}
# run.json field, its flag, its value in a run.json written before the field existed, another value
OPTIONS = [("mode_guidance", "--mode-guidance", 0.0, 2.0), ("noise_scale", "--noise-scale", 1.0, 0.0)]


@pytest.mark.parametrize("field, flag, before, other", OPTIONS)
def test_a_run_with_another_value_is_refused_naming_the_flag(tmp_path, field, flag, before, other):
    check_run(tmp_path, {**RUN, field: other})
    with pytest.raises(RunMismatchError, match=rf"{field} {other}, this run has {before}: use another --out "
                                                rf"\(or {flag} {other} to resume it\)"):
        check_run(tmp_path, {**RUN, field: before})
    assert check_run(tmp_path, {**RUN, field: other})[field] == other


@pytest.mark.parametrize("field, flag, before, other", OPTIONS)
def test_a_run_json_from_before_the_field_has_its_old_behaviour(tmp_path, field, flag, before, other):
    (tmp_path / "run.json").write_text(json.dumps(RUN))
    assert check_run(tmp_path, {**RUN, field: before})[field] == before
    with pytest.raises(RunMismatchError, match=f"{field} {before}, this run has 1.5"):
        check_run(tmp_path, {**RUN, field: 1.5})


@pytest.mark.parametrize("flag, message", [("--mode-guidance", "--mode-guidance -1.0 is not a weight >= 0"),
                                           ("--noise-scale", "--noise-scale -1.0 is not a scale >= 0")])
def test_a_negative_value_is_refused_before_any_sample(tmp_path, flag, message):
    result = subprocess.run(["actaim2", "evaluate", "--smoke", "--out", str(tmp_path / "out"), "--methods", "random",
                             flag, "-1"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and message in result.stderr, result.stderr
    assert not (tmp_path / "out").exists()


def test_a_policy_row_draws_its_modes_at_its_noise_scale(tmp_path):
    """What --noise-scale reaches in a worker (WorkerSetup -> PolicySource): at 0, one eps per cluster and views."""
    model = PolicyModel.load(make_checkpoint(tmp_path), load_perception_config("ring5").replace(resolution=RESOLUTION), "cpu")
    config = model.views_config("selector")
    views = Views(0, np.random.default_rng(0).uniform(0, 1, (5, len(config.channels), RESOLUTION, RESOLUTION)).astype(np.float32))
    spec = load_robot_spec("panda")
    for scale, same in ((0.0, True), (1.0, False)):
        source = PolicySource(model, spec, noise_scale=scale)
        first, second = (source.sample_mode(views, 1, seed).eps for seed in (1, 2))
        assert np.array_equal(first, second) == same
