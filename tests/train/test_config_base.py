"""Training YAMLs that start from another (``base:``): the ablation configs are the CPU default but for what they name."""
from __future__ import annotations

import dataclasses

import pytest

from actaim2.train.config import TrainConfig, load_config


def test_ablation_configs_are_the_cpu_default_but_for_phases_and_predictor_inputs():
    default = load_config("cpu_default")
    for name, inputs, view in (("ablation_depth", ["depth", "uv"], "all"), ("ablation_single_view", ["rgb", "xyz", "depth", "uv"], "back")):
        config = load_config(name)
        assert config.phases == ("predictor",)
        assert config.predictor == {**default.predictor, "inputs": inputs, "view": view}
        assert dataclasses.replace(config, phases=default.phases, predictor=default.predictor) == default


def test_a_base_merges_mappings_key_by_key_and_refuses_loops_and_unknown_keys(tmp_path):
    (tmp_path / "a.yaml").write_text("base: cpu_default\nselector_phase: {epochs: 3}\nselector: {obs: {token_dim: 32}}\n")
    config = load_config(tmp_path / "a.yaml")
    default = load_config("cpu_default")
    assert config.selector_phase == dataclasses.replace(default.selector_phase, epochs=3)
    assert config.selector.obs == dataclasses.replace(default.selector.obs, token_dim=32)
    (tmp_path / "loop.yaml").write_text(f"base: {tmp_path / 'loop.yaml'}\n")
    with pytest.raises(ValueError, match="names itself as a base"):
        load_config(tmp_path / "loop.yaml")
    (tmp_path / "typo.yaml").write_text("base: cpu_default\npredictor_phase: {epoch: 3}\n")
    with pytest.raises(ValueError, match=r"unknown predictor_phase field\(s\)"):
        load_config(tmp_path / "typo.yaml")


def test_point_pooling_is_structured_demos_but_for_the_pooling_and_ten_epochs():
    base = load_config("structured_demos")
    config = load_config("point_pooling")
    assert config.predictor == {**base.predictor, "rotation_pooling": "point"}
    assert config.predictor_phase == dataclasses.replace(base.predictor_phase, epochs=10)
    assert dataclasses.replace(config, predictor=base.predictor, predictor_phase=base.predictor_phase) == base


def test_rotation_smoothing_is_structured_demos_but_for_the_rotation_targets_and_ten_epochs():
    base = load_config("structured_demos")
    config = load_config("rotation_smoothing")
    assert config.rotation_sigma_deg == 10.0 and base.rotation_sigma_deg == 0.0
    assert config.predictor_phase == dataclasses.replace(base.predictor_phase, epochs=10)
    assert dataclasses.replace(config, rotation_sigma_deg=0.0, predictor_phase=base.predictor_phase) == base


def test_a_negative_rotation_sigma_is_refused(tmp_path):
    (tmp_path / "bad.yaml").write_text("base: cpu_default\nrotation_sigma_deg: -1.0\n")
    with pytest.raises(ValueError, match="rotation_sigma_deg must be >= 0"):
        load_config(tmp_path / "bad.yaml")


def test_the_third_steps_control_is_structured_demos_but_for_ten_epochs():
    base = load_config("structured_demos")
    config = load_config("third_step_control")
    assert config == dataclasses.replace(base, predictor_phase=dataclasses.replace(base.predictor_phase, epochs=10))
    for step in ("point_pooling", "rotation_smoothing", "film_conditioning", "eps_noise_off", "mode_query", "mode_contrast",
                 "augment_off", "mode_contrast_4", "mode_contrast_16"):
        assert load_config(step).predictor_phase == config.predictor_phase


def test_eps_noise_off_is_the_third_steps_control_but_for_the_noise():
    control, step = load_config("third_step_control"), load_config("eps_noise_off")
    assert control.eps_noise == 0.5 and step.eps_noise == 0.0
    assert dataclasses.replace(step, eps_noise=control.eps_noise) == control


def test_augment_off_is_the_third_steps_control_but_for_the_augmentation():
    control, step = load_config("third_step_control"), load_config("augment_off")
    assert control.augment and not step.augment
    assert dataclasses.replace(step, augment=True) == control


def test_the_mode_contrast_step_is_the_mode_query_step_but_for_the_contrast():
    query, step = load_config("mode_query"), load_config("mode_contrast")
    assert query.mode_contrast == 0.0 and step.mode_contrast == 1.0
    assert dataclasses.replace(step, mode_contrast=0.0) == query


def test_a_negative_mode_contrast_is_refused(tmp_path):
    (tmp_path / "bad.yaml").write_text("base: cpu_default\nmode_contrast: -0.5\n")
    with pytest.raises(ValueError, match="mode_contrast must be >= 0"):
        load_config(tmp_path / "bad.yaml")


def test_mode_from_scratch_is_the_mode_contrast_step_trained_fresh_for_twenty_epochs():
    contrast, step = load_config("mode_contrast"), load_config("mode_from_scratch")
    assert contrast.predictor_from_parent and not step.predictor_from_parent and step.predictor_phase.epochs == 20
    assert dataclasses.replace(step, predictor_from_parent=True, predictor_phase=contrast.predictor_phase) == contrast


def test_mode_contrast_4_is_the_mode_contrast_step_but_four_times_as_strong():
    contrast, step = load_config("mode_contrast"), load_config("mode_contrast_4")
    assert step.mode_contrast == 4.0 and dataclasses.replace(step, mode_contrast=1.0) == contrast


def test_mode_contrast_16_is_the_weight_4_step_but_four_times_as_strong_again():
    four, step = load_config("mode_contrast_4"), load_config("mode_contrast_16")
    assert step.mode_contrast == 16.0 and dataclasses.replace(step, mode_contrast=4.0) == four


def test_mode_contrast_4_long_is_the_weight_4_step_but_for_twenty_epochs():
    four, step = load_config("mode_contrast_4"), load_config("mode_contrast_4_long")
    assert step.predictor_phase.epochs == 20
    assert dataclasses.replace(step, predictor_phase=four.predictor_phase) == four


def test_mode_contrast_16_low_noise_is_the_weight_16_step_but_for_the_eps_noise():
    sixteen, step = load_config("mode_contrast_16"), load_config("mode_contrast_16_low_noise")
    assert sixteen.eps_noise == 0.5 and step.eps_noise == 0.1
    assert dataclasses.replace(step, eps_noise=0.5) == sixteen


def test_served_eps_is_the_weight_16_step_but_for_the_eps_the_predictor_reads():
    sixteen, step = load_config("mode_contrast_16"), load_config("served_eps")
    assert sixteen.predictor_eps == "true" and (step.predictor_eps, step.served_draws) == ("served", 8)
    assert dataclasses.replace(step, predictor_eps="true") == sixteen


@pytest.mark.parametrize("change, message", [({"predictor_eps": "drawn"}, "predictor_eps must be one of"),
                                             ({"served_draws": 0}, "served_draws must be >= 1")])
def test_a_bad_served_eps_setting_is_refused(change, message):
    with pytest.raises(ValueError, match=message):
        TrainConfig.from_dict(change)


def test_served_eps_long_is_the_served_step_but_for_twenty_epochs():
    served, step = load_config("served_eps"), load_config("served_eps_long")
    assert step.predictor_phase.epochs == 20
    assert dataclasses.replace(step, predictor_phase=served.predictor_phase) == served


def test_mode_query_lr_is_the_weight_16_step_but_for_the_conditioning_layers_rate():
    sixteen, step = load_config("mode_contrast_16"), load_config("mode_query_lr")
    assert sixteen.conditioning_lr_scale == 1.0 and step.conditioning_lr_scale == 10.0
    assert dataclasses.replace(step, conditioning_lr_scale=1.0) == sixteen


def test_a_conditioning_lr_scale_of_zero_is_refused():
    with pytest.raises(ValueError, match="conditioning_lr_scale must be > 0"):
        TrainConfig.from_dict({"conditioning_lr_scale": 0.0})


def test_cluster_information_is_the_cluster_balance_run_but_for_the_confidence_term():
    balance, step = load_config("cluster_balance"), load_config("cluster_information")
    assert balance.phases == ("selector",) and balance.elbo.cluster_balance == 1.0 and balance.elbo.cluster_confidence == 0.0
    assert dataclasses.replace(step, elbo=dataclasses.replace(step.elbo, cluster_confidence=0.0)) == balance


def test_cluster_information_10_is_the_same_run_at_ten_times_both_weights():
    one, ten = load_config("cluster_information"), load_config("cluster_information_10")
    assert (ten.elbo.cluster_balance, ten.elbo.cluster_confidence) == (10.0, 10.0)
    assert dataclasses.replace(ten, elbo=one.elbo) == one


def test_cluster_coverage_and_the_selector_condition_runs_differ_from_cluster_balance_in_their_one_setting():
    balance = load_config("cluster_balance")
    coverage, condition, both = (load_config(n) for n in ("cluster_coverage", "selector_condition",
                                                           "selector_condition_coverage"))
    plain = dataclasses.replace(balance, elbo=dataclasses.replace(balance.elbo, cluster_balance=0.0))
    assert coverage.elbo.cluster_coverage == 1.0 and dataclasses.replace(coverage, elbo=plain.elbo) == plain
    assert condition.selector_condition == "object" and dataclasses.replace(condition, selector_condition="own") == plain
    assert dataclasses.replace(both, elbo=plain.elbo) == condition and both.elbo == coverage.elbo


def test_selector_condition_coverage_10_is_the_same_run_at_ten_times_the_coverage():
    one, ten = load_config("selector_condition_coverage"), load_config("selector_condition_coverage_10")
    assert ten.elbo.cluster_coverage == 10.0 and dataclasses.replace(ten, elbo=one.elbo) == one


def test_fit_demos_is_structured_demos_without_augmentation_or_eps_noise():
    base, step = load_config("structured_demos"), load_config("fit_demos")
    assert base.augment and base.eps_noise == 0.5 and not step.augment and step.eps_noise == 0.0
    assert dataclasses.replace(step, augment=True, eps_noise=0.5) == base


def test_neighbour_eps_is_fit_demos_but_for_the_eps_the_predictor_reads_for_ten_epochs():
    fit, step = load_config("fit_demos"), load_config("neighbour_eps")
    assert (step.predictor_eps, step.neighbour_count, step.predictor_phase.epochs) == ("neighbour", 2, 10)
    assert dataclasses.replace(step, predictor_eps="true", predictor_phase=fit.predictor_phase) == fit


def test_neighbour_eps_balanced_is_neighbour_eps_with_cluster_balanced_keyframes():
    base, step = load_config("neighbour_eps"), load_config("neighbour_eps_balanced")
    assert base.predictor_balance == "none" and step.predictor_balance == "cluster"
    assert dataclasses.replace(step, predictor_balance="none") == base


def test_neighbour_eps_augmented_is_neighbour_eps_with_the_scene_augmentation():
    base, step = load_config("neighbour_eps"), load_config("neighbour_eps_augmented")
    assert not base.augment and step.augment
    assert dataclasses.replace(step, augment=False) == base


def test_a_neighbour_count_of_zero_is_refused():
    with pytest.raises(ValueError, match="neighbour_count must be >= 1"):
        TrainConfig.from_dict({"predictor_eps": "neighbour", "neighbour_count": 0})


def test_served_eps_noise_free_is_fit_demos_but_for_the_noise_free_served_draws_for_ten_epochs():
    fit, step = load_config("fit_demos"), load_config("served_eps_noise_free")
    assert (step.predictor_eps, step.served_draws, step.served_noise_scale, step.predictor_phase.epochs) == ("served", 1, 0.0, 10)
    assert dataclasses.replace(step, predictor_eps="true", served_draws=8, served_noise_scale=1.0,
                               predictor_phase=fit.predictor_phase) == fit


def test_nearest_centre_eps_is_fit_demos_but_for_the_eps_the_predictor_reads_for_ten_epochs():
    fit, step = load_config("fit_demos"), load_config("nearest_centre_eps")
    assert (step.predictor_eps, step.predictor_phase.epochs) == ("nearest_centre", 10)
    assert dataclasses.replace(step, predictor_eps="true", predictor_phase=fit.predictor_phase) == fit


def test_a_negative_served_noise_scale_is_refused():
    with pytest.raises(ValueError, match="served_noise_scale must be >= 0"):
        TrainConfig.from_dict({"predictor_eps": "served", "served_noise_scale": -1.0})
