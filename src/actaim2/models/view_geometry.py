"""Cube <-> view-pixel geometry of the action predictor: targets in, 3-D points out.

The predictor sees the workspace cube through the five orthographic views of
:mod:`actaim2.perception.ortho_views`, whose view axes and pixel mapping are the only
definition used here (:func:`~actaim2.perception.ortho_views.project`, called on cube-frame
points with centre 0 and half extent 1). This module adds what learning needs on top:

* :class:`CubePlacement` - where the cube sits in the world. Every learned quantity lives in the
  *cube frame* ``(world - center) / half_extent`` in [-1, 1]^3, the frame the renderer writes
  the views' xyz channels in (as RVT renders its normalised cloud): ground-truth positions are
  moved into it before they become heatmap targets (the authors' code skipped this step and
  trained on world positions against cube-frame views).
* :func:`heatmap_targets` - Gaussian (sigma 1.5 px) soft targets around a point's projections.
* :func:`depth_targets` and :func:`decode_points_in_view` - the same for a predictor that reads
  one view: one view cannot triangulate (all R cells on a pixel's ray have the same score), so
  the point is the heatmap's pixel at a depth cell predicted separately (Gaussian soft targets
  over the R cells along the view's ray, sigma 1.5 cells, as for the pixels).
* :func:`decode_points` - RVT's cube-grid re-projection: the 3-D point whose five projections
  carry the largest summed log-probability, searched coarse-to-fine: a 32^3 grid scored by an
  upper bound (per view, the best pixel of the cell's block), then the 9^3 fine cells around
  the 2 best coarse cells scored exactly. :func:`decode_cells_dense` scores all R^3 cells;
  tests use it to check the coarse-to-fine search (a dense search at 128 px was measured at
  460-780 ms per call on 2 cores, far over the 20 ms latency budget).
  With ``sigma_px`` > 0 every view's probabilities are first blurred by a Gaussian of that many
  pixels (:func:`smoothed_log_probs`), so the search finds the point with the most mass *around*
  its projections rather than the single likeliest pixel. Why: an under-fitted predictor's
  heatmap spreads over a whole part with pixel-level speckle, and the plain argmax lands on a
  speckle anywhere in the spread (``PredictorConfig.decode_sigma_px``; 0, RVT's argmax, by default).

Candidates are the *fine lattice*: R^3 cells (R = view resolution), whose centres project onto
pixel centres in every view, so a candidate's score is an exact sum of five pixel values.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch
import torch.nn.functional as F

from actaim2.perception.ortho_views import VIEWS, project, unproject

HEATMAP_SIGMA = 1.5  # px, RVT's Gaussian target width
COARSE_CELLS = 32  # cells per axis of the coarse decode grid
FINE_RADIUS = 4  # fine cells searched on each side of a coarse cell's middle: a 9^3 neighbourhood
REFINED_CELLS = 2  # coarse cells whose neighbourhoods are searched (2: an almost-tied second mode is not lost)


@dataclass(frozen=True)
class CubePlacement:
    """The rendered cube ``center +- half_extent`` (world metres): the perception configuration's."""

    center: tuple[float, float, float]
    half_extent: float

    @classmethod
    def of(cls, config) -> "CubePlacement":
        """The placement of a configuration with ``center`` and ``half_extent`` (FusionConfig, PerceptionConfig)."""
        return cls(tuple(float(c) for c in config.center), float(config.half_extent))

    def to_cube(self, world: torch.Tensor) -> torch.Tensor:
        """(..., 3) world metres -> cube frame, [-1, 1] inside the cube."""
        center = torch.as_tensor(self.center, dtype=world.dtype, device=world.device)
        return (world - center) / self.half_extent

    def contains(self, world: torch.Tensor) -> torch.Tensor:
        """(...,) whether world points (..., 3) lie inside the cube, where they can be targets."""
        return self.to_cube(world).abs().amax(dim=-1) <= 1.0

    def to_world(self, cube: torch.Tensor) -> torch.Tensor:
        """(..., 3) cube frame -> world metres (the inverse of :meth:`to_cube`)."""
        center = torch.as_tensor(self.center, dtype=cube.dtype, device=cube.device)
        return cube * self.half_extent + center


def project_cube(points: torch.Tensor, resolution: int) -> torch.Tensor:
    """Continuous pixel coordinates (u, v) of cube-frame points in every view: (N, V, 2).

    Integer parts are pixel indices (u = column, v = row); ortho_views' projection does the work.
    """
    u, v, _ = project(points.detach().cpu().double().numpy(), (0.0, 0.0, 0.0), 1.0, resolution)
    return torch.from_numpy(np.stack([u, v], axis=-1)).transpose(0, 1).to(points.device, torch.float32)


def heatmap_targets(points: torch.Tensor, resolution: int, sigma: float = HEATMAP_SIGMA) -> torch.Tensor:
    """(N, V, R, R) soft targets: per view a Gaussian around the point's projection, summing to 1.

    The Gaussian is evaluated at pixel centres (index + 0.5), as the projection's continuous
    coordinates place pixel i over [i, i + 1).
    """
    uv = project_cube(points, resolution)  # (N, V, 2)
    centres = torch.arange(resolution, dtype=torch.float32, device=points.device) + 0.5
    g = torch.exp(-((centres - uv[..., None]) ** 2) / (2.0 * sigma**2))  # (N, V, 2, R)
    maps = g[:, :, 1, :, None] * g[:, :, 0, None, :]  # rows (v) x columns (u)
    return maps / maps.sum(dim=(-2, -1), keepdim=True)


def depth_targets(points: torch.Tensor, view: int, resolution: int, sigma: float = HEATMAP_SIGMA) -> torch.Tensor:
    """(N, R) soft targets over the R fine-lattice cells along ``view``'s ray, summing to 1.

    Cell j covers depths [j, j + 1) * (2 / R) from the view's face (cube frame, side 2): the
    same lattice as the pixels, so a pixel and a depth cell name one fine cell.
    """
    _, _, depth = project(points.detach().cpu().double().numpy(), (0.0, 0.0, 0.0), 1.0, resolution)
    d = torch.from_numpy(depth[view] * resolution / 2.0).to(points.device, torch.float32)  # (N,) in cells
    centres = torch.arange(resolution, dtype=torch.float32, device=points.device) + 0.5
    g = torch.exp(-((centres - d[:, None]) ** 2) / (2.0 * sigma**2))
    return g / g.sum(dim=-1, keepdim=True)


@torch.no_grad()
def decode_points_in_view(heatmap: torch.Tensor, depth_logits: torch.Tensor, view: int, sigma_px: float = 0.0) -> torch.Tensor:
    """(B, R, R) heatmap logits of one view and (B, R) depth-cell logits -> (B, 3) cube-frame point.

    The most likely pixel (of the heatmap blurred by ``sigma_px``, as :func:`decode_points`) and
    the most likely depth cell (independent outputs, so this is the joint argmax): the centre of
    that fine cell, exactly as :func:`decode_points` returns one.
    """
    b, resolution, _ = heatmap.shape
    pixel = smoothed_log_probs(heatmap[:, None], sigma_px).argmax(dim=1)
    row, column = divmod(pixel.cpu().numpy(), resolution)
    depth = (depth_logits.argmax(dim=1).cpu().numpy() + 0.5) * (2.0 / resolution)
    point = unproject(view, column, row, depth, (0.0, 0.0, 0.0), 1.0, resolution)
    return torch.from_numpy(point.reshape(b, 3)).to(heatmap.device, torch.float32)


def cell_centres(cells: torch.Tensor, resolution: int) -> torch.Tensor:
    """Cube-frame centres of fine-lattice cells given as (..., 3) integer indices in [0, R)."""
    return (cells.to(torch.float32) + 0.5) * (2.0 / resolution) - 1.0


def _pixel_index(cells: torch.Tensor, resolution: int) -> torch.Tensor:
    """(N, V) flat index (view * R^2 + row * R + column) of the pixel each cell projects onto."""
    uv = project_cube(cell_centres(cells, resolution), resolution).floor().long().clamp_(0, resolution - 1)
    view = torch.arange(len(VIEWS), device=cells.device) * resolution * resolution
    return view + uv[..., 1] * resolution + uv[..., 0]


@lru_cache(maxsize=4)
def _coarse_grid(coarse: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Coarse cells (C^3, 3) and the flat index of their block in each view's C x C pooled map.

    Views are axis-aligned, so the fine cells of one coarse cell project onto one aligned block
    of (R / C)^2 pixels in every view: the block of the coarse lattice's own projection.
    """
    axis = torch.arange(coarse)
    cells = torch.cartesian_prod(axis, axis, axis)
    return cells, _pixel_index(cells, coarse)


def smoothed_log_probs(heatmaps: torch.Tensor, sigma_px: float = 0.0) -> torch.Tensor:
    """(B, V, R, R) logits -> (B, V * R * R) per-view log-probabilities, blurred by a Gaussian of ``sigma_px``.

    The blur is separable, truncated at 3 sigma, with the border pixels repeated outwards (mass
    near a view's edge is not diluted by the zeros outside it). ``sigma_px`` 0: the plain log-softmax.
    """
    b, v, h, w = heatmaps.shape
    log_probs = F.log_softmax(heatmaps.reshape(b, v, h * w).float(), dim=-1)
    if sigma_px <= 0.0:
        return log_probs.reshape(b, v * h * w)
    radius = max(1, math.ceil(3.0 * sigma_px))
    taps = torch.arange(-radius, radius + 1, dtype=torch.float32, device=heatmaps.device)
    kernel = torch.exp(-(taps**2) / (2.0 * sigma_px**2))
    kernel = kernel / kernel.sum()
    probs = F.pad(log_probs.exp().reshape(b * v, 1, h, w), (radius,) * 4, mode="replicate")
    probs = F.conv2d(F.conv2d(probs, kernel.view(1, 1, 1, -1)), kernel.view(1, 1, -1, 1))
    return probs.clamp_min(torch.finfo(torch.float32).tiny).log().reshape(b, v * h * w)


def _scores(log_probs: torch.Tensor, pixels: torch.Tensor) -> torch.Tensor:
    """(B, N) summed log-probabilities of candidates given by their pixels, (N, V) or (B, N, V)."""
    if pixels.dim() == 2:
        return log_probs[:, pixels].sum(dim=-1)
    return torch.gather(log_probs, 1, pixels.flatten(1)).view(pixels.shape).sum(dim=-1)


@torch.no_grad()
def score_cells(heatmaps: torch.Tensor, cells: torch.Tensor, sigma_px: float = 0.0) -> torch.Tensor:
    """(B, N) score of fine cells (B, N, 3): the sum over views of the (blurred) log-probabilities at their pixels."""
    b, n, _ = cells.shape
    pixels = _pixel_index(cells.reshape(-1, 3), heatmaps.shape[-1]).view(b, n, len(VIEWS))
    return _scores(smoothed_log_probs(heatmaps, sigma_px), pixels)


@torch.no_grad()
def decode_cells(
    heatmaps: torch.Tensor, coarse: int = COARSE_CELLS, radius: int = FINE_RADIUS, refine: int = REFINED_CELLS,
    sigma_px: float = 0.0,
) -> torch.Tensor:
    """(B, V, R, R) heatmap logits -> (B, 3) fine-lattice cell of the best point, coarse-to-fine.

    A coarse cell is scored by the sum over views of the *largest* log-probability in its block
    (max pooling): an upper bound of every fine score inside it, so a sharp peak that falls
    between coarse sample points is not missed. The ``refine`` best coarse cells then have their
    (2 radius + 1)^3 fine neighbourhoods scored exactly; the best fine cell wins.
    """
    b, v, resolution, _ = heatmaps.shape
    if resolution % coarse:
        raise ValueError(f"the coarse grid ({coarse}) must divide the view resolution ({resolution})")
    step = resolution // coarse
    log_probs = smoothed_log_probs(heatmaps, sigma_px)
    pooled = F.max_pool2d(log_probs.view(b * v, 1, resolution, resolution), step).view(b, -1)
    cells, pixels = _coarse_grid(coarse)
    top = _scores(pooled, pixels.to(heatmaps.device)).topk(refine, dim=1).indices  # (B, refine)
    middle = cells.to(heatmaps.device)[top] * step + step // 2  # (B, refine, 3) fine cells
    offsets = torch.arange(-radius, radius + 1, device=heatmaps.device)
    fine = (middle[:, :, None, :] + torch.cartesian_prod(offsets, offsets, offsets)).reshape(b, -1, 3).clamp_(0, resolution - 1)
    fine_pixels = _pixel_index(fine.reshape(-1, 3), resolution).view(b, -1, v)
    k = _scores(log_probs, fine_pixels).argmax(dim=1)
    return fine[torch.arange(b, device=heatmaps.device), k]


@torch.no_grad()
def decode_cells_dense(heatmaps: torch.Tensor, sigma_px: float = 0.0) -> torch.Tensor:
    """The same as :func:`decode_cells` by scoring every one of the R^3 cells (slow: tests only)."""
    b, v, resolution, _ = heatmaps.shape
    log_probs = smoothed_log_probs(heatmaps, sigma_px)
    axis = torch.arange(resolution, device=heatmaps.device)
    all_cells = torch.cartesian_prod(axis, axis, axis)
    chunk = max(4096, (1 << 23) // (b * v))  # bounds the (B, chunk, V) gather to 32 MB
    best_score = torch.full((b,), -torch.inf, device=heatmaps.device)
    best_cell = torch.zeros(b, 3, dtype=torch.long, device=heatmaps.device)
    for start in range(0, len(all_cells), chunk):
        cells = all_cells[start : start + chunk]
        score, k = _scores(log_probs, _pixel_index(cells, resolution)).max(dim=1)
        better = score > best_score
        best_score = torch.where(better, score, best_score)
        best_cell[better] = cells[k[better]]
    return best_cell


def decode_points(heatmaps: torch.Tensor, sigma_px: float = 0.0) -> torch.Tensor:
    """(B, V, R, R) heatmap logits -> (B, 3) cube-frame point (the best fine cell's centre)."""
    return cell_centres(decode_cells(heatmaps, sigma_px=sigma_px), heatmaps.shape[-1])
