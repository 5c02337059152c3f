"""actaim2.policy without ROS: loading and checking a checkpoint, the two inferences, request
validation with reasons, views acceptance, the episode plan, success judgement, records, backoff."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from actaim2.models.rotation_bins import grasp_geodesic_deg
from actaim2.perception.config import load_perception_config
from actaim2.perception.ortho_views import VIEWS
from actaim2.policy.episodes import (
    EpisodeLog,
    EpisodeRecord,
    PhaseRecord,
    largest_change,
    plan_episodes,
    summary_table,
)
from actaim2.policy.inference import PolicyLoadError, PolicyModel
from actaim2.policy.locate import describe, resolve_checkpoint
from actaim2.policy.requests import RequestError, check_fresh, is_transient
from actaim2.policy.retry import Backoff, wait_until
from actaim2.policy.views import Views, accept_views
from tiny_policy import TARGETS


@pytest.fixture(scope="module")
def model(tiny_checkpoint) -> PolicyModel:
    loaded = PolicyModel.load(tiny_checkpoint.stem, tiny_checkpoint.config, "cpu")
    assert loaded.warm_up() > 0
    return loaded


def scene(tiny_checkpoint, index: int = 0, stamp: int = 5) -> Views:
    return Views(stamp, tiny_checkpoint.views[index])


def test_the_checkpoint_is_found_by_path_or_by_name_in_a_folder(tiny_checkpoint, tmp_path):
    stem = tiny_checkpoint.stem
    assert resolve_checkpoint(stem) == stem
    assert resolve_checkpoint(stem.with_suffix(".json")) == stem
    assert resolve_checkpoint(stem.name, [tmp_path, stem.parent]) == stem
    with pytest.raises(FileNotFoundError, match=r"not found \(looked for .*nowhere/policy.json"):
        resolve_checkpoint("policy", [tmp_path / "nowhere"])


def test_the_description_names_the_runs_a_continued_checkpoint_came_from(tiny_checkpoint, tmp_path):
    """A run continued twice (--init-from) names its own phases, then each run it continued."""
    meta = json.loads(tiny_checkpoint.stem.with_suffix(".json").read_text())
    first = {"path": "runs/a/policy", "weights_sha256": "aaaa1111" * 8, "phases_done": ["selector", "predictor", "joint"],
             "predictor_loaded": True, "init_from": None}
    second = {"path": "runs/b/policy", "weights_sha256": "bbbb2222" * 8, "phases_done": ["predictor"],
              "predictor_loaded": True, "init_from": first}
    meta["lineage"] = {**meta.get("lineage", {}), "phases_done": ["predictor"], "init_from": second}
    (tmp_path / "continued.json").write_text(json.dumps(meta))
    text = describe(tmp_path / "continued")
    assert text.endswith("trained phases: predictor; continued from bbbb2222 (phases: predictor); "
                         "continued from aaaa1111 (phases: selector, predictor, joint))"), text
    assert describe(tiny_checkpoint.stem).count("continued from") == 0


def test_a_checkpoint_trained_under_another_perception_configuration_is_refused_naming_the_fields(tiny_checkpoint):
    serving = load_perception_config("ring5")  # 128 px: the checkpoint's views are 64 px
    with pytest.raises(PolicyLoadError, match=r"resolution: 64 != 128"):
        PolicyModel.load(tiny_checkpoint.stem, serving, "cpu")
    with pytest.raises(PolicyLoadError, match=r"rig: 'ring5' != 'azure_kinect'"):
        PolicyModel.load(tiny_checkpoint.stem, load_perception_config("azure_kinect").replace(resolution=64), "cpu")


def test_a_corrupt_checkpoint_is_refused_with_the_reason(tiny_checkpoint, tmp_path):
    for suffix in (".json", ".safetensors"):
        shutil.copy(tiny_checkpoint.stem.with_suffix(suffix), tmp_path / f"policy{suffix}")
    with open(tmp_path / "policy.safetensors", "r+b") as f:
        f.seek(200)
        f.write(b"\x00" * 16)
    with pytest.raises(PolicyLoadError, match="corrupted or was replaced"):
        PolicyModel.load(tmp_path / "policy", tiny_checkpoint.config, "cpu")


def test_sample_mode_is_reproducible_per_seed_and_honours_a_requested_cluster(model, tiny_checkpoint):
    views = scene(tiny_checkpoint)
    a, b, c = (model.sample_mode(views, -1, seed, noise_scale=1.0) for seed in (7, 7, 8))
    np.testing.assert_array_equal(a.eps, b.eps)
    assert not np.array_equal(a.eps, c.eps)  # the trained distribution: the seed draws eps
    # the default (noise scale 0, as policy_node serves): one eps per cluster and views, whatever the seed
    np.testing.assert_array_equal(model.sample_mode(views, 2, 7).eps, model.sample_mode(views, 2, 8).eps)
    assert a.eps.shape == (model.embedding_dim,) and np.isclose(a.probabilities.sum(), 1.0) and 0 <= a.cluster < 4
    assert model.sample_mode(views, 2, 7).cluster == 2


def test_predict_keypose_decodes_the_trained_keyposes_in_world(model, tiny_checkpoint):
    views = scene(tiny_checkpoint, 1)
    eps = model.sample_mode(views, -1, 3).eps
    for phase, target in enumerate(TARGETS):
        prediction = model.predict_keypose(views, eps, phase, phase == 3)
        kp = prediction.keypose
        assert kp.phase == phase and kp.gripper_closed == bool(target[7])
        # 64 px over a 1.2 m cube: 19 mm pixels; 72 rotation bins of 5 degrees
        assert np.linalg.norm(kp.position - target[:3]) < 0.04, (phase, kp.position)
        assert abs(np.dot(kp.quat_xyzw, target[3:7])) > np.cos(np.radians(8) / 2)
        assert 0.0 < prediction.confidence <= 1.0
        assert prediction.alternatives == ()  # none unless asked for


def test_alternatives_share_the_point_and_gripper_with_rotations_a_grasp_apart(model, tiny_checkpoint):
    views = scene(tiny_checkpoint, 1)
    eps = model.sample_mode(views, -1, 3).eps
    plain = model.predict_keypose(views, eps, 1, False)
    prediction = model.predict_keypose(views, eps, 1, False, alternatives=3, separation_deg=30.0)
    assert prediction.keypose.to_json() == plain.keypose.to_json() and prediction.confidence == plain.confidence
    assert len(prediction.alternatives) == 3
    quats = [plain.keypose.quat_xyzw] + [k.quat_xyzw for k in prediction.alternatives]
    for k in prediction.alternatives:
        assert k.phase == 1 and k.gripper_closed == plain.keypose.gripper_closed
        np.testing.assert_array_equal(k.position, plain.keypose.position)
    for i in range(len(quats)):
        for j in range(i):
            assert grasp_geodesic_deg(quats[i][None], quats[j][None])[0] >= 30.0 - 1e-6


@pytest.mark.parametrize("embedding, phase, reason", [
    (np.zeros(19), 0, "embedding has 19 values, the checkpoint's predictor expects 20"),
    (np.r_[np.zeros(19), np.nan], 0, r"NaN or infinite values \(1 of 20\)"),
    (np.r_[np.full(18, np.inf), 0, 0], 0, r"NaN or infinite values \(18 of 20\)"),
    (np.zeros(20), 4, r"unknown phase 4: expected one of 0 \(INIT\), 1 \(REACH\), 2 \(GRASP\), 3 \(MANIPULATE\)"),
])
def test_bad_predict_requests_say_what_is_wrong(model, tiny_checkpoint, embedding, phase, reason):
    with pytest.raises(RequestError, match=reason):
        model.predict_keypose(scene(tiny_checkpoint), embedding, phase, False)


@pytest.mark.parametrize("cluster", [4, -2, 100])
def test_unknown_clusters_are_refused(model, tiny_checkpoint, cluster):
    with pytest.raises(RequestError, match=rf"unknown cluster {cluster}: the mode selector has 4 clusters \(0..3\)"):
        model.sample_mode(scene(tiny_checkpoint), cluster, 0)


def test_views_are_accepted_only_under_the_checkpoints_configuration(tiny_checkpoint):
    config = tiny_checkpoint.config
    data = tiny_checkpoint.views[0]
    fields = (64, 64, list(VIEWS), list(config.channels))
    views = accept_views(12, *fields, data.ravel(), config.digest(), config)
    assert views.stamp_ns == 12 and views.data.shape == data.shape
    other = load_perception_config("ring5")
    with pytest.raises(RequestError, match=rf"made under perception configuration {other.digest()} but the checkpoint expects"):
        accept_views(12, *fields, data.ravel(), other.digest(), config)
    with pytest.raises(RequestError, match="layout"):
        accept_views(12, 32, 32, list(VIEWS), list(config.channels), data.ravel(), config.digest(), config)
    with pytest.raises(RequestError, match="carry 100 values"):
        accept_views(12, *fields, np.zeros(100, np.float32), config.digest(), config)


def test_stale_views_are_refused_and_known_as_transient():
    check_fresh(2_000_000_000, 2_000_000_000)
    with pytest.raises(RequestError, match=r"stale observation: .* 1.000 s, before not_before 2.000 s") as error:
        check_fresh(1_000_000_000, 2_000_000_000)
    assert is_transient(str(error.value)) and is_transient("no views yet: nothing received")
    assert not is_transient("checkpoint failed to load: x")


def test_each_model_gets_the_robot_filter_setting_it_was_trained_with(tiny_checkpoint, tmp_path):
    for suffix in (".json", ".safetensors"):
        shutil.copy(tiny_checkpoint.stem.with_suffix(suffix), tmp_path / f"policy{suffix}")
    meta = json.loads((tmp_path / "policy.json").read_text())
    meta["robot_filter"] = {"selector": True, "predictor": False}
    (tmp_path / "policy.json").write_text(json.dumps(meta))
    model = PolicyModel.load(tmp_path / "policy", tiny_checkpoint.config, "cpu")
    selector, predictor = model.views_config("selector"), model.views_config("predictor")
    assert selector.remove_robot_views and not predictor.remove_robot_views
    assert selector.digest() == tiny_checkpoint.config.digest() != predictor.digest()


def test_episode_plan_visits_every_object_before_the_next_cluster():
    plan = plan_episodes(5, ["drawer", "door"], [0, -1], [""], [-1, 3], seed=10)
    assert [(s.category, s.instance, s.cluster, s.seed) for s in plan] == [
        ("drawer", 0, -1, 10), ("drawer", -1, -1, 11), ("door", 0, -1, 12), ("door", -1, -1, 13), ("drawer", 0, 3, 14)]
    folders = plan_episodes(3, ["drawer"], [0], ["/a", "/b"], [-1], seed=0)
    assert [(s.object_path, s.category) for s in folders] == [("/a", ""), ("/b", ""), ("/a", "")]
    with pytest.raises(ValueError, match="no cluster"):
        plan_episodes(1, ["drawer"], [0], [""], [], 0)


def test_success_is_judged_against_the_resets_initial_state_and_limits():
    args = (["j1", "j2"], [0.1, 0.0], [0.0, -1.0], [0.3, 1.0])
    assert largest_change(*args, ["j2", "x", "j1"], [0.5, 9.0, 0.16]) == pytest.approx(0.25)
    assert largest_change(*args, ["j1", "j2"], [0.0, 0.0]) == pytest.approx(1 / 3)
    with pytest.raises(ValueError, match=r"lacks the DoF\(s\) \['j2'\]"):
        largest_change(*args, ["j1"], [0.1])


def test_records_are_strict_json_lines_and_the_summary_counts_ssr(tmp_path):
    log = EpisodeLog(tmp_path / "runs" / "e.jsonl")
    ok = EpisodeRecord(0, "policy", "drawer", 0, "", 0, -1, object_id="drawer_000", cluster=1, success=True,
                       phases=[PhaseRecord(0, {"phase": 0}, 0.5, 1.0, 0.9, True, "ok")])
    bad = EpisodeRecord(1, "policy", "drawer", 0, "", 1, -1, object_id="drawer_000", cluster=1,
                        note="embedding contains NaN or infinite values")
    for r in (ok, bad):
        log.append(r)
    lines = [json.loads(line) for line in (tmp_path / "runs" / "e.jsonl").read_text().splitlines()]
    assert lines[0]["phases"][0]["position_error"] is None and lines[1]["reset_stamp"] is None
    assert lines[1]["note"] == "embedding contains NaN or infinite values"
    table = summary_table([ok, bad])
    assert "| drawer_000 | 1 | 2 | 1 | 50 % |" in table and "| all | | 2 | 1 | 50 % |" in table


def test_backoff_grows_to_its_cap_and_never_passes_the_deadline():
    assert Backoff(0.25, 2.0, 1.0).delays(3.0) == [0.25, 0.5, 1.0, 1.0, 0.25]
    calls = []
    assert not wait_until(lambda: calls.append(1) and False, 0.3, sleep=lambda s: False)
    assert len(calls) == 1 + len(Backoff().delays(0.3))
    assert wait_until(lambda: calls.append(1) or len(calls) > 6, 10.0, sleep=lambda s: False)
    assert not wait_until(lambda: False, 10.0, stop=lambda: True)


def test_a_checkpoint_decoding_blurred_heatmaps_is_served_so_and_a_bad_blur_refused(tiny_checkpoint, tmp_path):
    """``decode_sigma_px`` in the checkpoint's JSON is how /predict_keypose decodes its heatmaps."""
    import torch

    from actaim2.models.predictor import decode_action, proprio_features

    meta = json.loads(tiny_checkpoint.stem.with_suffix(".json").read_text())
    shutil.copy(tiny_checkpoint.stem.with_suffix(".safetensors"), tmp_path / "policy.safetensors")
    meta["predictor_config"]["decode_sigma_px"] = 2.0
    (tmp_path / "policy.json").write_text(json.dumps(meta))
    blurred = PolicyModel.load(tmp_path / "policy", tiny_checkpoint.config, "cpu")
    views = scene(tiny_checkpoint, 1)
    eps = blurred.sample_mode(views, -1, 3).eps
    batch = torch.from_numpy(np.ascontiguousarray(views.data))[None]
    for phase, target in enumerate(TARGETS):
        served = blurred.predict_keypose(views, eps, phase, phase == 3).keypose.position
        proprio = proprio_features(torch.tensor([phase == 3]), torch.tensor([phase]))
        with torch.no_grad():
            out = blurred.predictor(batch, torch.from_numpy(eps)[None], proprio)
        expected = decode_action(out, blurred.placement, None, 2.0).position[0].double().numpy()
        np.testing.assert_allclose(served, expected, atol=1e-6)
        assert np.linalg.norm(served - target[:3]) < 0.04, (phase, served)
    meta["predictor_config"]["decode_sigma_px"] = 100.0
    (tmp_path / "policy.json").write_text(json.dumps(meta))
    with pytest.raises(PolicyLoadError, match="decode_sigma_px must lie in"):
        PolicyModel.load(tmp_path / "policy", tiny_checkpoint.config, "cpu")
