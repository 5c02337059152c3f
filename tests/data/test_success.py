"""The visual success label's model, reach, threshold, metrics and calibration rules, and the ground-truth criterion."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.data.labelling import calibrate, object_reaches, success_scores, visual_labels
from actaim2.data.part_motion import PartMotion
from actaim2.data.success import (
    SuccessModel,
    calibrate_threshold,
    change,
    label_metrics,
    motion_features,
    part_reaches,
)
from actaim2.data.trajectory import ObjectState, ground_truth_success


def rotation(angle_deg: float, radius: float, axis: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> PartMotion:
    return PartMotion(points=500, angle=float(np.radians(angle_deg)), shift=radius * np.radians(angle_deg) / 2,
                      displacement=2 * radius * np.sin(np.radians(angle_deg) / 2), radius=radius, extent=radius,
                      residual=0.0015, axis=axis)


def translation(shift: float, extent: float, axis: tuple[float, float, float] = (1.0, 0.0, 0.0)) -> PartMotion:
    return PartMotion(points=500, angle=0.0, shift=shift, displacement=shift, radius=0.0, extent=extent,
                      residual=0.0015, axis=axis)


def _synthetic_parts(rng: np.random.Generator, n: int) -> tuple[list[PartMotion], np.ndarray]:
    """Doors (0.4 m, ranges 70-95 deg), toggles-sized levers (3 cm, 40-60 deg) and drawers (0.2-0.3 m
    travel) moved by a uniform share of their range from half-open; ground truth: > 30%."""
    parts, gt = [], []
    for k in range(n):
        moved = rng.uniform(0.0, 0.5)
        kind = k % 3
        if kind == 0:
            parts.append(rotation(moved * rng.uniform(70, 95), 0.4 + rng.uniform(-0.05, 0.05)))
        elif kind == 1:
            parts.append(rotation(moved * rng.uniform(40, 60), 0.03 + rng.uniform(-0.005, 0.005)))
        else:
            parts.append(translation(moved * rng.uniform(0.2, 0.3), 0.5 + rng.uniform(-0.1, 0.1)))
        gt.append(moved > 0.3)
    return parts, np.array(gt)


def test_the_model_puts_the_30_percent_mark_by_kind_of_part():
    parts, gt = _synthetic_parts(np.random.default_rng(0), 600)
    model = calibrate([[p] for p in parts], gt)
    test_parts, test_gt = _synthetic_parts(np.random.default_rng(1), 600)
    labels = success_scores([[p] for p in test_parts], model) > model.threshold
    assert abs(model.threshold - 0.5) < 0.15  # the accuracy-optimal cut stays near the likelihood's
    assert label_metrics(labels, test_gt)["accuracy"] > 0.93
    # the same 20 degrees: a failure for a door (~23% of its range), a success for a toggle (~40%)
    def p(part: PartMotion) -> float:
        return model.probability(motion_features(part))

    assert p(rotation(20.0, 0.4)) < model.threshold < p(rotation(20.0, 0.03))
    assert p(rotation(35.0, 0.4)) > model.threshold
    assert p(translation(0.03, 0.5)) < model.threshold < p(translation(0.12, 0.5))
    assert SuccessModel.from_json(model.to_json()) == model
    assert success_scores([[]], model)[0] == 0.0  # nothing moved: no success


def test_the_mark_of_a_small_lever_depends_on_its_axis():
    """data/v2's faucets: a lever lifted at the side about a horizontal axis has a 40-55 deg range,
    one turned on top about a vertical axis 80-130 deg; both 7 cm long. 25 degrees is a success
    for the first (~50%) and a failure for the second (~25%): the model must see the axis."""
    rng = np.random.default_rng(3)
    parts, gt = [], []
    for k in range(600):
        moved, arm = rng.uniform(0.0, 0.6), rng.uniform(0.06, 0.08)
        horizontal = k % 2 == 0
        span = rng.uniform(40, 55) if horizontal else rng.uniform(80, 130)
        parts.append(rotation(moved * span, arm, (1.0, 0.0, 0.0) if horizontal else (0.0, 0.0, 1.0)))
        gt.append(moved > 0.3)
    model = calibrate([[p] for p in parts], np.array(gt))
    labels = success_scores([[p] for p in parts], model) > model.threshold
    assert label_metrics(labels, np.array(gt))["accuracy"] > 0.93

    def p(part: PartMotion) -> float:
        return model.probability(motion_features(part))

    assert p(rotation(25.0, 0.07, (0.0, 0.0, 1.0))) < model.threshold < p(rotation(25.0, 0.07, (1.0, 0.0, 0.0)))
    assert p(rotation(12.0, 0.07, (1.0, 0.0, 0.0))) < model.threshold < p(rotation(45.0, 0.07, (0.0, 0.0, 1.0)))


def test_calibration_needs_both_outcomes_and_skips_ambiguous_successes():
    parts, gt = _synthetic_parts(np.random.default_rng(2), 60)
    assert calibrate([[p] for p in parts[:3]], gt[:3]) is None  # too few to calibrate
    with pytest.raises(ValueError, match="both outcomes"):
        SuccessModel.fit(np.stack([motion_features(p) for p in parts]), np.zeros(len(parts), bool))
    # a success with two moved parts does not say which one moved far: it must not pull the door's mark down
    door_nudge, drawer_pull = rotation(10.0, 0.4), translation(0.14, 0.5)
    with_ambiguous = calibrate([[p] for p in parts] + [[door_nudge, drawer_pull]] * 30, np.r_[gt, np.ones(30, bool)])
    assert with_ambiguous.weights == calibrate([[p] for p in parts], gt).weights
    entries = [{"id": f"t{k}", "object_id": f"o{k}", "split": "train_seen", "gt_success": bool(g)} for k, g in enumerate(gt)]
    scores, model, calibrated = visual_labels(entries, {f"t{k}": [p] for k, p in enumerate(parts)})
    assert calibrated and label_metrics(scores > model.threshold, gt)["accuracy"] > 0.9
    with pytest.raises(ValueError, match="calibration split"):
        visual_labels(entries, {f"t{k}": [p] for k, p in enumerate(parts)},
                      calibration_splits=("train_unseen_instance",))


def test_a_reach_needs_two_trajectories_at_the_same_stop():
    door = [rotation(a, 0.4) for a in (5.0, 12.0, 40.0, 38.5)]  # two opened to the stop at ~40 deg
    toggle = [rotation(a, 0.03, (1.0, 0.0, 0.0)) for a in (25.0, 24.0)]  # another axis: another part
    drawer = [translation(s, 0.5, (-1.0, 0.0, 0.0)) for s in (0.02, 0.15)] + [translation(0.14, 0.5)]  # either sign
    lone = [translation(s, 0.3, (0.0, 1.0, 0.0)) for s in (0.01, 0.05)]  # farthest motion alone: unknown
    reaches = part_reaches([[p] for p in door + toggle + drawer + lone] + [[]])
    assert reaches[-1] == []
    np.testing.assert_allclose([r[0] for r in reaches[:-1]], [39.25] * 4 + [24.5] * 2 + [0.145] * 3 + [0.0] * 2)
    entries = [{"id": f"{o}-{k}", "object_id": o} for o in ("a", "b") for k in range(2)]
    motions = {"a-0": [door[2]], "a-1": [door[3]], "b-0": [door[2]], "b-1": [door[0]]}
    assert object_reaches(entries, motions) == [[39.25], [39.25], [0.0], [0.0]]  # per object only


def _object(rng: np.random.Generator, kind: str, n: int = 20) -> tuple[list[list[PartMotion]], np.ndarray]:
    """One object's trajectories from half-open: a part moved by a share of its range up to its stop
    at 50% (measured within 2%); ground truth: > 30%. A "stuck" door stops after 3-8 deg."""
    span = {"door": rng.uniform(70, 95), "lever": rng.uniform(40, 60), "drawer": rng.uniform(0.2, 0.3),
            "lid": 0.12, "stuck": rng.uniform(70, 95)}[kind]
    stop = rng.uniform(3, 8) / span if kind == "stuck" else 0.5
    size = {"door": 0.4, "lever": 0.03, "drawer": 0.5, "lid": 0.3, "stuck": 0.4}[kind] * rng.uniform(0.9, 1.1)
    parts, gt = [], []
    for moved in np.minimum(rng.uniform(0.0, 0.8, n), stop):
        travel = moved * span * rng.normal(1.0, 0.02)
        if kind in ("drawer", "lid"):
            parts.append([translation(travel, size, (float(rng.choice([-1.0, 1.0])), 0.0, 0.0))])
        else:
            parts.append([rotation(travel, size, (1.0, 0.0, 0.0) if kind == "lever" else (0.0, 0.0, 1.0))])
        gt.append(moved > 0.3)
    return parts, np.array(gt)


def _objects(rng: np.random.Generator, kinds: list[str]) -> tuple[list[list[PartMotion]], np.ndarray, list[list[float]]]:
    parts, gt, reaches = [], [], []
    for kind in kinds:
        p, g = _object(rng, kind)
        parts, gt, reaches = parts + p, np.r_[gt, g], reaches + part_reaches(p)
    return parts, gt, reaches


def test_the_reach_places_the_mark_of_a_part_kind_the_calibration_lacks():
    """Calibrated on doors, levers and 0.2-0.3 m drawers, a box's 0.12 m sliding lid gets a drawer's
    mark (~7 cm) from the absolute terms alone; its reach, read off its object's trajectories, moves
    the mark onto the lid's own range (35% of it sits at the mark, as data/v2's box lids do; 20% and
    40% are told apart). A door that stops after a few degrees is no success although its
    trajectories pile up at that stop: the absolute terms set no per-object quota."""
    rng = np.random.default_rng(4)
    parts, gt, reaches = _objects(rng, ["door", "lever", "drawer", "stuck"] * 12)
    model, without = calibrate(parts, gt, reaches), calibrate(parts, gt)
    for kinds, least in ((["door", "lever", "drawer"] * 4, 0.95), (["lid"] * 6, 0.85)):
        test_parts, test_gt, test_reaches = _objects(rng, kinds)
        labels = success_scores(test_parts, model, test_reaches) > model.threshold
        assert label_metrics(labels, test_gt)["balanced_accuracy"] > least, kinds
    assert label_metrics(success_scores(test_parts, without) > without.threshold, test_gt)["balanced_accuracy"] < 0.6  # lids
    lid, _ = _object(rng, "lid")
    lid_reach = max(r[0] for r in part_reaches(lid))
    assert lid_reach == pytest.approx(0.06, rel=0.05)  # half its range: the lids start half-open
    p20, p40 = (model.probability(motion_features(translation(f * 0.12, 0.3), lid_reach)) for f in (0.2, 0.4))
    assert p20 < model.threshold < p40
    assert without.probability(motion_features(translation(0.4 * 0.12, 0.3))) < without.threshold  # a drawer moved 16-24%
    for _ in range(5):
        stuck, _ = _object(rng, "stuck")
        reach = part_reaches(stuck)
        assert max(r[0] for r in reach) > 0  # the pile at the stop is found ...
        assert not (success_scores(stuck, model, reach) > model.threshold).any()  # ... and is no success


def test_threshold_separates_and_matches_brute_force():
    rng = np.random.default_rng(0)
    s = np.r_[rng.normal(0.0, 1.0, 300), rng.normal(3.0, 1.0, 60)]
    gt = np.r_[np.zeros(300, bool), np.ones(60, bool)]
    t = calibrate_threshold(s, gt)
    best = max(label_metrics(s > c, gt)["accuracy"] for c in np.r_[s - 1e-9, s + 1e-9])
    assert label_metrics(s > t, gt)["accuracy"] == best
    m = label_metrics(np.array([True, True, False, False]), np.array([True, False, True, False]))
    assert (m["accuracy"], m["balanced_accuracy"], m["precision"], m["recall"]) == (0.5, 0.5, 0.5, 0.5)
    assert m["false_positives"] == m["false_negatives"] == 1


def test_change_is_rms_of_z():
    np.testing.assert_allclose(change(np.array([[3.0, 4.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])), [2.5, 0.0])


def test_ground_truth_is_thirty_percent_of_the_range():
    state = ObjectState(["door", "drawer"], np.array([0.0, 0.0]), np.array([1.5, 0.4]), np.array([0.75, 0.2]), np.array([0.75, 0.2]))
    assert not ground_truth_success(state)
    state.final = np.array([0.75, 0.2 - 0.13])  # drawer closed by 32.5% of its range
    assert ground_truth_success(state)
    state.final = np.array([0.75 + 0.4, 0.2])  # door opened by 26.7%
    assert not ground_truth_success(state)
