"""Input ablations of the action predictor: depth-only and single-view inputs, and the single-view decode."""
from __future__ import annotations

import pytest
import torch

from actaim2.models.predictor import (
    ActionPredictor,
    PredictorConfig,
    PredictorOutput,
    decode_action,
    proprio_features,
)
from actaim2.models.view_geometry import (
    decode_points_in_view,
    depth_targets,
    heatmap_targets,
    score_cells,
)
from actaim2.perception.ortho_views import CHANNELS, VIEWS
from actaim2.train.action_loss import action_loss, action_targets
from test_predictor import EMBEDDING, PLACEMENT, keyposes, random_views, tiny_config
from test_view_geometry import R, random_world_points

RGB_XYZ = [CHANNELS.index(c) for c in "rgbxyz"]
DEPTH = CHANNELS.index("depth")


def outputs(model: ActionPredictor, views: torch.Tensor) -> PredictorOutput:
    torch.manual_seed(1)
    eps, proprio = torch.randn(2, EMBEDDING), proprio_features(torch.tensor([0, 1]), torch.tensor([1, 3]))
    with torch.no_grad():
        return model.eval()(views, eps, proprio)


def assert_same(a: PredictorOutput, b: PredictorOutput) -> None:
    for x, y in zip(a, b):
        assert (x is None and y is None) or torch.equal(x, y)


def changed(a: PredictorOutput, b: PredictorOutput) -> bool:
    return any(not torch.equal(x, y) for x, y in zip(a, b) if x is not None)


def test_depth_only_predictor_does_not_read_rgb_or_xyz():
    torch.manual_seed(0)
    depth_only = ActionPredictor(tiny_config(inputs=("depth", "uv")))
    full = ActionPredictor(tiny_config())
    views = random_views(2, 64, 0)
    other_colour = views.clone()
    other_colour[:, :, RGB_XYZ] = torch.rand(other_colour[:, :, RGB_XYZ].shape)
    other_depth = views.clone()
    other_depth[:, :, DEPTH] = torch.rand(other_depth[:, :, DEPTH].shape)
    assert_same(outputs(depth_only, views), outputs(depth_only, other_colour))
    assert changed(outputs(depth_only, views), outputs(depth_only, other_depth))
    assert changed(outputs(full, views), outputs(full, other_colour))  # the full predictor does read them
    assert depth_only.parameter_count() < full.parameter_count()  # a smaller patch embedding: 4 inputs, not 10


def test_single_view_predictor_reads_its_view_only_and_predicts_a_depth():
    torch.manual_seed(0)
    config = tiny_config(view="back")
    model = ActionPredictor(config)
    back = VIEWS.index("back")
    views = random_views(2, 64, 1)
    others = views.clone()
    others[:, [i for i in range(len(VIEWS)) if i != back]] = random_views(2, 64, 2)[:, [i for i in range(len(VIEWS)) if i != back]]
    its_own = views.clone()
    its_own[:, back] = random_views(2, 64, 3)[:, back]
    out = outputs(model, views)
    assert out.heatmaps.shape == (2, 1, 64, 64) and out.depth.shape == (2, 64)
    assert_same(out, outputs(model, others))
    assert changed(out, outputs(model, its_own))
    assert config.view_index == back and PredictorConfig.from_json(config.to_json()) == config


def test_single_view_loss_and_decode_agree_on_the_targets():
    """Outputs equal to a single-view predictor's targets decode to the keypose (within one cell)
    and its loss has a depth term: without it one view cannot place the point along its ray."""
    view = VIEWS.index("top")
    kp = keyposes([[0.7, -0.2, 0.3], [0.2, 0.4, 0.9]], seed=1)
    targets = action_targets(kp, PLACEMENT, 64, view=view)
    assert targets.heatmaps.shape == (2, 1, 64, 64) and targets.depth.shape == (2, 64)
    rotation = torch.nn.functional.one_hot(targets.rotation_bins, 72).float() * 10
    gripper = torch.nn.functional.one_hot(targets.gripper, 2).float() * 10
    out = PredictorOutput(targets.heatmaps.clamp_min(1e-30).log(), rotation, gripper, targets.depth.clamp_min(1e-30).log())
    decoded = decode_action(out, PLACEMENT, view)
    assert (decoded.position - kp[:, :3]).abs().max() <= 2 * PLACEMENT.half_extent / 64
    with pytest.raises(ValueError, match="view index"):
        decode_action(out, PLACEMENT)
    flat = out._replace(depth=torch.zeros(2, 64))  # a uniform depth costs log 64 more than the target's entropy
    assert float(action_loss(flat, targets)[1]["translation"]) > float(action_loss(out, targets)[1]["translation"]) + 1.0


@pytest.mark.parametrize("view", range(len(VIEWS)))
def test_single_view_round_trip_recovers_the_point_within_one_cell(view):
    """A point -> its one view's heatmap and depth target -> the point, within one cube-grid cell per axis."""
    world = random_world_points(200, 10 + view)
    cube = PLACEMENT.to_cube(world).float()
    heatmap = heatmap_targets(cube, R)[:, view].clamp_min(1e-30).log()
    depth = depth_targets(cube, view, R).clamp_min(1e-30).log()
    recovered = PLACEMENT.to_world(decode_points_in_view(heatmap, depth, view).double())
    assert (recovered - world).abs().max() <= 2 * PLACEMENT.half_extent / R


def test_one_view_alone_cannot_place_a_point_along_its_ray():
    """Why a single-view predictor needs its depth output: with the other four views flat, the
    cube-grid score is the same for every cell on the pixel's ray."""
    view = VIEWS.index("front")  # looks along -x: every cell of one (y, z) projects onto one pixel
    point = torch.tensor([[0.1, 0.2, -0.3]])
    logits = torch.zeros(1, len(VIEWS), R, R)
    logits[:, view] = heatmap_targets(point, R)[:, view].clamp_min(1e-30).log()
    _, y, z = ((point[0] + 1) * R / 2).floor().long().tolist()
    ray = torch.tensor([[x, y, z] for x in range(R)])
    scores = score_cells(logits, ray[None])
    torch.testing.assert_close(scores, scores[:, :1].expand_as(scores))
    assert float(scores[0, 0]) > float(score_cells(logits, torch.tensor([[[0, y + 3, z]]]))[0, 0])  # off the ray: lower


@pytest.mark.parametrize("change, message", [
    (dict(inputs=("colour",)), "inputs must be distinct groups"),
    (dict(inputs=("uv",), channel_names=("x", "y", "z"), in_channels=3), "select none of the rendered channels"),
    (dict(view="side"), "view must be"),
    (dict(channel_names=("r", "g", "b")), "must name the 8 rendered channels"),
])
def test_bad_ablation_configs_are_refused(change, message):
    with pytest.raises(ValueError, match=message):
        tiny_config(**change)
