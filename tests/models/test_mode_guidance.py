"""Mode guidance (models/mode_guidance.py): CFG's formula on the heatmaps, the rest untouched, and what it decodes."""
from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F

from actaim2.models.mode_guidance import guide, with_reference
from actaim2.models.predictor import PredictorOutput, decode_action
from actaim2.models.view_geometry import CubePlacement, heatmap_targets

PLACEMENT = CubePlacement((0.5, 0.0, 0.4), 0.6)


def _pair(conditional: torch.Tensor, reference: torch.Tensor, depth: bool = False) -> PredictorOutput:
    """A forward pass's output of [eps row; reference row]: the given heatmaps, distinct rotation and gripper rows."""
    heatmaps = torch.stack([conditional, reference])
    rotation = torch.arange(2 * 3 * 72, dtype=torch.float32).reshape(2, 3, 72)
    gripper = torch.tensor([[0.0, 1.0], [1.0, 0.0]])
    return PredictorOutput(heatmaps, rotation, gripper, torch.randn(2, heatmaps.shape[-1]) if depth else None)


def test_the_reference_rows_are_the_mean_mode() -> None:
    eps = torch.randn(3, 16)
    batch = with_reference(eps)
    assert batch.shape == (6, 16)
    assert torch.equal(batch[:3], eps) and not batch[3:].any()


def test_guided_heatmaps_follow_the_classifier_free_guidance_formula() -> None:
    torch.manual_seed(0)
    conditional, reference = torch.randn(5, 8, 8), torch.randn(5, 8, 8)
    out = guide(_pair(conditional, reference), 2.0)
    lc = F.log_softmax(conditional.reshape(5, -1), -1)
    lr = F.log_softmax(reference.reshape(5, -1), -1)
    expected = F.log_softmax(lc + 2.0 * (lc - lr), -1).reshape(1, 5, 8, 8)
    assert torch.allclose(out.heatmaps, expected, atol=1e-5)
    assert torch.allclose(out.heatmaps.exp().sum(dim=(-2, -1)), torch.ones(1, 5))  # still log-probabilities per view
    # rotation and gripper are the eps row's own logits
    pair = _pair(conditional, reference)
    assert torch.equal(out.rotation, pair.rotation[:1]) and torch.equal(out.gripper, pair.gripper[:1])


def test_weight_zero_decodes_the_plain_heatmap() -> None:
    torch.manual_seed(1)
    conditional, reference = torch.randn(5, 64, 64), torch.randn(5, 64, 64)
    plain = PredictorOutput(conditional[None], torch.zeros(1, 3, 72), torch.zeros(1, 2))
    guided = guide(_pair(conditional, reference), 0.0)
    assert torch.allclose(decode_action(guided, PLACEMENT).position, decode_action(plain, PLACEMENT).position)


def _peak(cube_point: list[float]) -> torch.Tensor:
    """(5, 64, 64) logits 0..1 peaked at the point's projection in every view."""
    target = heatmap_targets(torch.tensor([cube_point]), 64)[0]
    return target / target.amax(dim=(-2, -1), keepdim=True)


def test_guidance_moves_the_point_to_what_eps_adds() -> None:
    """Both rows put most mass at A; eps adds some at B. The plain argmax keeps A, guidance picks B."""
    a, b = [-0.4, -0.3, -0.2], [0.4, 0.3, 0.2]
    reference = 6.0 * _peak(a)
    conditional = reference + 5.0 * _peak(b)  # below A in the eps row, but only there
    pair = _pair(conditional, reference)
    plain = decode_action(PredictorOutput(conditional[None], pair.rotation[:1], pair.gripper[:1]), PLACEMENT).position
    guided = decode_action(guide(pair, 1.0), PLACEMENT).position
    assert torch.allclose(plain[0], PLACEMENT.to_world(torch.tensor([a]))[0], atol=0.03)
    assert torch.allclose(guided[0], PLACEMENT.to_world(torch.tensor([b]))[0], atol=0.03)


def test_single_view_depth_cells_are_guided_too() -> None:
    torch.manual_seed(2)
    out = guide(_pair(torch.randn(1, 8, 8), torch.randn(1, 8, 8), depth=True), 1.5)
    assert out.depth.shape == (1, 8)
    assert torch.allclose(out.depth.exp().sum(-1), torch.ones(1))


def test_a_negative_weight_is_refused() -> None:
    with pytest.raises(ValueError, match="negative"):
        guide(_pair(torch.randn(5, 8, 8), torch.randn(5, 8, 8)), -1.0)
