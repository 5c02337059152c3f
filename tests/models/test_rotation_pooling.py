"""Where the rotation/gripper head reads its features: RVT-1's heatmap mean or RVT-2's point.

The point pooling must read, at serving, the token under the point the outputs decode to (the
same token training read at the demonstrated point), and only that token.
"""
from __future__ import annotations

import pytest
import torch

from actaim2.models.predictor import ActionPredictor, PredictorConfig, proprio_features
from actaim2.models.view_geometry import decode_points, decode_points_in_view, project_cube
from actaim2.perception.ortho_views import VIEWS
from actaim2.train.action_loss import action_loss, action_targets
from test_predictor import EMBEDDING, PLACEMENT, keyposes, random_views, tiny_config


def _inputs(batch: int = 3, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    proprio = proprio_features(torch.tensor([0, 1, 0])[:batch], torch.tensor([0, 1, 2])[:batch])
    return random_views(batch, 64, seed), torch.randn(batch, EMBEDDING, generator=g), proprio


def test_config_names_the_pooling_and_old_checkpoints_read_the_heatmap():
    assert tiny_config().rotation_pooling == "heatmap"
    old = tiny_config().to_json()
    del old["rotation_pooling"]  # a checkpoint saved before the field existed
    assert PredictorConfig.from_json(old).rotation_pooling == "heatmap"
    with pytest.raises(ValueError, match="rotation_pooling"):
        tiny_config(rotation_pooling="centre")


def test_heatmap_pooling_ignores_the_demonstrated_point():
    torch.manual_seed(0)
    model = ActionPredictor(tiny_config()).eval()
    views, eps, proprio = _inputs()
    with torch.no_grad():
        free = model(views, eps, proprio)
        forced = model(views, eps, proprio, point=torch.zeros(3, 3))
    torch.testing.assert_close(free.rotation, forced.rotation)


def test_point_pooling_serves_the_decoded_point_as_training_reads_a_given_one():
    torch.manual_seed(0)
    model = ActionPredictor(tiny_config(rotation_pooling="point")).eval()
    views, eps, proprio = _inputs()
    with torch.no_grad():
        served = model(views, eps, proprio)
        at_decoded = model(views, eps, proprio, point=decode_points(served.heatmaps))
        elsewhere = model(views, eps, proprio, point=-decode_points(served.heatmaps).clamp(-0.9, 0.9) * 0.9 + 0.3)
    torch.testing.assert_close(served.heatmaps, at_decoded.heatmaps)
    torch.testing.assert_close(served.rotation, at_decoded.rotation)
    torch.testing.assert_close(served.gripper, at_decoded.gripper)
    assert not torch.allclose(served.rotation, elsewhere.rotation)


def test_point_pooling_reads_only_the_token_under_the_point():
    """Two points in the same patch of every view give the same outputs; the other views' and
    the other patches' contents reach them only through attention."""
    torch.manual_seed(0)
    model = ActionPredictor(tiny_config(rotation_pooling="point")).eval()
    views, eps, proprio = _inputs(batch=1)
    patch_side = 2.0 / (64 // 8)  # cube-frame side of one 8 px patch
    centre = torch.full((1, 3), 0.5 * patch_side)  # the centre of a patch in every axis
    nudged = centre + 0.2 * patch_side
    moved = centre + 1.0 * patch_side
    with torch.no_grad():
        a, b, c = (model(views, eps, proprio, point=p).rotation for p in (centre, nudged, moved))
    def cells(p: torch.Tensor) -> torch.Tensor:
        return (project_cube(p, 64) / 8).floor()

    assert torch.equal(cells(centre), cells(nudged)) and not torch.equal(cells(centre), cells(moved))
    torch.testing.assert_close(a, b)
    assert not torch.allclose(a, c)


def test_single_view_point_pooling_serves_the_heatmap_argmax_pixel():
    torch.manual_seed(0)
    view = 1
    model = ActionPredictor(tiny_config(rotation_pooling="point", view=VIEWS[view])).eval()
    views, eps, proprio = _inputs()
    with torch.no_grad():
        served = model(views, eps, proprio)
        pixel = served.heatmaps[:, 0].flatten(1).argmax(dim=1)
        row, column = pixel // 64, pixel % 64
        # A point on that pixel's ray (any depth) projects into the argmax pixel of the one view.
        point = decode_points_in_view(served.heatmaps[:, 0], torch.zeros(3, 64), view)
        uv = project_cube(point, 64)[:, view].floor().long()
        assert torch.equal(uv[:, 0], column) and torch.equal(uv[:, 1], row)
        forced = model(views, eps, proprio, point=point)
    torch.testing.assert_close(served.rotation, forced.rotation)
    torch.testing.assert_close(served.depth, forced.depth)


def test_point_pooling_trains_every_parameter_and_overfits_rotation():
    torch.manual_seed(0)
    model = ActionPredictor(tiny_config(rotation_pooling="point"))
    kp = keyposes([[0.6, 0.1, 0.3], [0.3, -0.2, 0.6], [0.9, 0.3, 0.2]], seed=3)
    targets = action_targets(kp, PLACEMENT, 64)
    views, eps, proprio = _inputs()
    point = PLACEMENT.to_cube(kp[:, :3])
    optimiser = torch.optim.AdamW(model.parameters(), lr=3e-3)
    history = []
    for step in range(60):
        loss, parts = action_loss(model(views, eps, proprio, point=point), targets)
        optimiser.zero_grad()
        loss.backward()
        if step == 0:
            dead = [name for name, p in model.named_parameters() if p.grad is None or not bool(p.grad.abs().gt(0).any())]
            assert not dead
        optimiser.step()
        history.append(float(parts["rotation"]))
    assert history[-1] < 0.2 * history[0], history[::10]
