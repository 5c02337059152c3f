"""Cube <-> view geometry: placement, heatmap targets against the renderer, decode round trip, dense check."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from actaim2.models.view_geometry import (
    CubePlacement,
    cell_centres,
    decode_cells,
    decode_cells_dense,
    decode_points,
    heatmap_targets,
    score_cells,
    smoothed_log_probs,
)
from actaim2.perception.ortho_views import CHANNELS, VIEWS, project, render_views

PLACEMENT = CubePlacement((0.5, 0.0, 0.4), 0.6)  # the default FusionConfig cube
R = 128


def random_world_points(n: int, seed: int, margin: float = 0.0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    cube = (torch.rand(n, 3, generator=g, dtype=torch.float64) * 2 - 1) * (1 - margin)
    return PLACEMENT.to_world(cube)


def test_cube_placement_and_its_inverse_return_the_point():
    world = random_world_points(1000, 0)
    cube = PLACEMENT.to_cube(world)
    assert cube.abs().max() <= 1.0 and PLACEMENT.contains(world).all()
    torch.testing.assert_close(PLACEMENT.to_world(cube), world, rtol=0, atol=1e-12)
    corner = torch.tensor([[1.1, 0.6, 1.0]], dtype=torch.float64)  # centre + half extent
    torch.testing.assert_close(PLACEMENT.to_cube(corner), torch.ones(1, 3, dtype=torch.float64))
    assert not PLACEMENT.contains(torch.tensor([[1.2, 0.0, 0.4]])).any()


def test_heatmap_targets_peak_where_the_renderer_draws_the_point():
    """A world point moved into the cube frame must peak on the pixel that holds it in the world
    projection, one of those render_views splats it onto: targets built from world coordinates
    (the authors' bug) peak elsewhere."""
    for point in random_world_points(20, 1, margin=0.05).numpy():
        views = render_views(point[None].astype(np.float32), np.array([[255, 255, 255]], np.uint8), PLACEMENT.center, PLACEMENT.half_extent, R)
        u, v, _ = project(point, PLACEMENT.center, PLACEMENT.half_extent, R)
        target = heatmap_targets(PLACEMENT.to_cube(torch.from_numpy(point)[None]), R)[0]
        assert target.shape == (len(VIEWS), R, R)
        torch.testing.assert_close(target.sum(dim=(1, 2)), torch.ones(len(VIEWS)))
        for i in range(len(VIEWS)):
            row, column = divmod(int(target[i].argmax()), R)
            assert (column, row) == (int(np.floor(u[i, 0])), int(np.floor(v[i, 0]))), VIEWS[i]
            assert views[i, CHANNELS.index("occupancy"), row, column] > 0, VIEWS[i]


def test_heatmap_round_trip_recovers_the_point_within_one_cell():
    world = random_world_points(200, 2)
    logits = heatmap_targets(PLACEMENT.to_cube(world), R).clamp_min(1e-30).log()
    recovered = PLACEMENT.to_world(decode_points(logits).double())
    cell = 2 * PLACEMENT.half_extent / R  # 9.4 mm
    assert (recovered - world).abs().max() <= cell


def _heatmap_sets(n: int, seed: int) -> torch.Tensor:
    """Logits of n heatmap sets: a third clean Gaussians of random width, a third with noise,
    a third bimodal with per-view mixing weights (the second mode stronger in some views)."""
    g = torch.Generator().manual_seed(seed)
    first = torch.rand(n, 3, generator=g) * 1.9 - 0.95
    second = torch.rand(n, 3, generator=g) * 1.9 - 0.95
    sigma = 1.5 + 2.5 * torch.rand(n, generator=g)
    maps = torch.cat([heatmap_targets(first[i : i + 1], R, float(sigma[i])) for i in range(n)])
    k = n // 3
    logits = maps.clamp_min(1e-12).log()
    logits[k : 2 * k] += 0.3 * torch.randn(logits[k : 2 * k].shape, generator=g)
    weight = 0.2 + 0.6 * torch.rand(n - 2 * k, len(VIEWS), 1, 1, generator=g)
    mixed = weight * maps[2 * k :] + (1 - weight) * heatmap_targets(second[2 * k :], R)
    logits[2 * k :] = mixed.clamp_min(1e-12).log()
    return logits


@pytest.mark.parametrize("sigma_px", [0.0, 3.0])
def test_coarse_to_fine_decode_matches_the_dense_argmax_on_100_heatmap_sets(sigma_px):
    logits = _heatmap_sets(100, 3)
    fast, dense = decode_cells(logits, sigma_px=sigma_px), decode_cells_dense(logits, sigma_px=sigma_px)
    fast_score = score_cells(logits, fast[:, None], sigma_px)[:, 0]
    dense_score = score_cells(logits, dense[:, None], sigma_px)[:, 0]
    torch.testing.assert_close(fast_score, dense_score, rtol=0, atol=1e-5)
    tied = torch.isclose(fast_score, dense_score, rtol=0, atol=1e-5) & (fast != dense).any(dim=1)
    assert ((fast == dense).all(dim=1) | tied).all()
    assert (fast == dense).all(dim=1).sum() >= 95  # exact ties between distinct cells are rare


def test_decode_rejects_a_coarse_grid_that_does_not_divide_the_views():
    with pytest.raises(ValueError, match="divide"):
        decode_cells(torch.zeros(1, len(VIEWS), 120, 120), coarse=32)


def test_cell_centres_tile_the_cube():
    centres = cell_centres(torch.tensor([[0, 0, 0], [R - 1, R - 1, R - 1]]), R)
    torch.testing.assert_close(centres, torch.tensor([[-1 + 1 / R] * 3, [1 - 1 / R] * 3]))


def test_smoothed_log_probs_without_blur_is_the_log_softmax_and_with_blur_a_distribution():
    logits = _heatmap_sets(6, 4)
    plain = smoothed_log_probs(logits)
    torch.testing.assert_close(plain, torch.log_softmax(logits.flatten(2), dim=-1).flatten(1))
    blurred = smoothed_log_probs(logits, 3.0).view(6, len(VIEWS), -1).exp()
    assert blurred.sum(dim=-1).sub(1).abs().max() < 0.05  # the repeated border keeps the mass up to the edge's share
    assert blurred.amax(dim=-1).le(plain.view(6, len(VIEWS), -1).exp().amax(dim=-1) + 1e-6).all()  # a blur lowers peaks


def test_smoothed_decode_finds_the_spread_part_not_a_single_speckle():
    """Most of the mass spread over one region and a single likeliest pixel elsewhere (a speckle):
    the plain argmax decodes the speckle, the blurred search the region, as decode_points says."""
    part = torch.tensor([[0.3, -0.2, 0.1]])
    speckle = torch.tensor([[-0.5, 0.4, -0.3]])
    spread = heatmap_targets(part, R, 6.0)  # the region: a wide Gaussian, peak ~0.4 % of a view's mass
    spike = heatmap_targets(speckle, R, 0.3)  # one pixel per view
    logits = (0.9 * spread + 0.1 * spike).log()
    cell = 2.0 / R
    assert (decode_points(logits) - speckle).abs().max() <= cell
    assert (decode_points(logits, 3.0) - part).abs().max() <= 2 * cell
