"""Cube <-> view-pixel geometry of the action predictor: targets in, 3-D points out.

The predictor sees the workspace cube through the five orthographic views of
:mod:`actaim2.perception.ortho_views`, whose view axes and pixel mapping are the only
definition used here (:func:`~actaim2.perception.ortho_views.project`, called on cube-frame
points with centre 0 and half extent 1). This module adds what learning needs on top:

* :class:`CubePlacement` - where the cube sits in the world. Every learned quantity lives in the
  *cube frame* ``(world - center) / half_extent`` in [-1, 1]^3: ground-truth positions are moved
  into it before they become heatmap targets (the authors' code skipped this step and trained on
  world positions against cube-frame views), and the views' xyz/depth channels are expressed in
  it (:func:`normalize_views`), as RVT renders its normalised cloud.
* :func:`heatmap_targets` - Gaussian (sigma 1.5 px) soft targets around a point's projections.
* :func:`decode_points` - RVT's cube-grid re-projection: the 3-D point whose five projections
  carry the largest summed log-probability, searched coarse-to-fine (a 32^3 grid, then the 9^3
  fine cells around the best coarse cell). :func:`decode_points_dense` scores all R^3 cells;
  tests use it to check the coarse-to-fine search (the dense search took 460-780 ms per call on
  2 cores, too slow for the 20 ms latency budget).

Candidates are the *fine lattice*: R^3 cells (R = view resolution), whose centres project onto
pixel centres in every view, so a candidate's score is an exact sum of five pixel values.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import torch
import torch.nn.functional as F

from actaim2.perception.ortho_views import CHANNELS, VIEWS, project

HEATMAP_SIGMA = 1.5  # px, RVT's Gaussian target width
COARSE_CELLS = 32  # cells per axis of the coarse decode grid
FINE_RADIUS = 4  # fine cells searched on each side of the best coarse cell: a 9^3 neighbourhood

_XYZ = [CHANNELS.index(c) for c in "xyz"]
_DEPTH = CHANNELS.index("depth")
_OCCUPANCY = CHANNELS.index("occupancy")


@dataclass(frozen=True)
class CubePlacement:
    """The rendered cube ``center +- half_extent`` (world metres): the perception configuration's."""

    center: tuple[float, float, float]
    half_extent: float

    @classmethod
    def of(cls, fusion) -> "CubePlacement":
        """The placement of a :class:`actaim2.perception.fusion.FusionConfig`."""
        return cls(tuple(float(c) for c in fusion.center), float(fusion.half_extent))

    def to_cube(self, world: torch.Tensor) -> torch.Tensor:
        """(..., 3) world metres -> cube frame, [-1, 1] inside the cube."""
        center = torch.as_tensor(self.center, dtype=world.dtype, device=world.device)
        return (world - center) / self.half_extent

    def to_world(self, cube: torch.Tensor) -> torch.Tensor:
        """(..., 3) cube frame -> world metres (the inverse of :meth:`to_cube`)."""
        center = torch.as_tensor(self.center, dtype=cube.dtype, device=cube.device)
        return cube * self.half_extent + center


def normalize_views(views: torch.Tensor, placement: CubePlacement) -> torch.Tensor:
    """Rendered views (..., len(CHANNELS), R, R) in world units -> the predictor's input units.

    xyz become cube-frame coordinates and depth a fraction of the cube side (0..1); colour and
    occupancy are unchanged. Empty pixels stay 0 in every channel, so occupancy still tells them
    apart. Without this, xyz would carry the rig's placement and the same scene in another cube
    would look different to the network.
    """
    out = views.clone()
    occupied = views[..., _OCCUPANCY : _OCCUPANCY + 1, :, :] > 0
    center = torch.as_tensor(placement.center, dtype=views.dtype, device=views.device).view(3, 1, 1)
    xyz = (views[..., _XYZ, :, :] - center) / placement.half_extent
    out[..., _XYZ, :, :] = torch.where(occupied, xyz, torch.zeros_like(xyz))
    out[..., _DEPTH, :, :] = views[..., _DEPTH, :, :] / (2.0 * placement.half_extent)
    return out


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


def cell_centres(cells: torch.Tensor, resolution: int) -> torch.Tensor:
    """Cube-frame centres of fine-lattice cells given as (..., 3) integer indices in [0, R)."""
    return (cells.to(torch.float32) + 0.5) * (2.0 / resolution) - 1.0


def _pixel_index(cells: torch.Tensor, resolution: int) -> torch.Tensor:
    """(N, V) flat index (view * R^2 + row * R + column) of the pixel each cell projects onto."""
    uv = project_cube(cell_centres(cells, resolution), resolution).floor().long().clamp_(0, resolution - 1)
    view = torch.arange(len(VIEWS), device=cells.device) * resolution * resolution
    return view + uv[..., 1] * resolution + uv[..., 0]


@lru_cache(maxsize=4)
def _coarse_grid(resolution: int, coarse: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Coarse candidates as fine cells (C^3, 3) and their pixel indices (C^3, V), cached per size.

    Coarse cell I spans fine cells [I*s, (I+1)*s) with s = R / C; its candidate is the fine cell
    I*s + s // 2 at its middle, so every coarse score is also an exact fine-lattice score.
    """
    if resolution % coarse:
        raise ValueError(f"the coarse grid ({coarse}) must divide the view resolution ({resolution})")
    step = resolution // coarse
    axis = torch.arange(coarse) * step + step // 2
    cells = torch.cartesian_prod(axis, axis, axis)
    return cells, _pixel_index(cells, resolution)


def _log_probs(heatmaps: torch.Tensor) -> torch.Tensor:
    """(B, V, R, R) logits -> (B, V * R * R) per-view log-probabilities."""
    b, v, h, w = heatmaps.shape
    return F.log_softmax(heatmaps.reshape(b, v, h * w).float(), dim=-1).reshape(b, v * h * w)


def _scores(log_probs: torch.Tensor, pixels: torch.Tensor) -> torch.Tensor:
    """(B, N) summed log-probabilities of candidates given by their pixels, (N, V) or (B, N, V)."""
    if pixels.dim() == 2:
        return log_probs[:, pixels].sum(dim=-1)
    return torch.gather(log_probs, 1, pixels.flatten(1)).view(pixels.shape).sum(dim=-1)


@torch.no_grad()
def score_cells(heatmaps: torch.Tensor, cells: torch.Tensor) -> torch.Tensor:
    """(B, N) score of fine cells (B, N, 3): the sum over views of log-softmax at their pixels."""
    b, n, _ = cells.shape
    pixels = _pixel_index(cells.reshape(-1, 3), heatmaps.shape[-1]).view(b, n, len(VIEWS))
    return _scores(_log_probs(heatmaps), pixels)


@torch.no_grad()
def decode_cells(heatmaps: torch.Tensor, coarse: int = COARSE_CELLS, radius: int = FINE_RADIUS) -> torch.Tensor:
    """(B, V, R, R) heatmap logits -> (B, 3) fine-lattice cell of the best point, coarse-to-fine."""
    b, _, resolution, _ = heatmaps.shape
    log_probs = _log_probs(heatmaps)
    cells, pixels = _coarse_grid(resolution, coarse)
    best = cells.to(heatmaps.device)[_scores(log_probs, pixels.to(heatmaps.device)).argmax(dim=1)]  # (B, 3)
    offsets = torch.arange(-radius, radius + 1, device=heatmaps.device)
    fine = (best[:, None, :] + torch.cartesian_prod(offsets, offsets, offsets)[None]).clamp_(0, resolution - 1)
    fine_pixels = _pixel_index(fine.reshape(-1, 3), resolution).view(b, -1, len(VIEWS))
    k = _scores(log_probs, fine_pixels).argmax(dim=1)
    return fine[torch.arange(b, device=heatmaps.device), k]


@torch.no_grad()
def decode_cells_dense(heatmaps: torch.Tensor) -> torch.Tensor:
    """The same as :func:`decode_cells` by scoring every one of the R^3 cells (slow: tests only)."""
    b, v, resolution, _ = heatmaps.shape
    log_probs = _log_probs(heatmaps)
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


def decode_points(heatmaps: torch.Tensor, coarse: int = COARSE_CELLS, radius: int = FINE_RADIUS) -> torch.Tensor:
    """(B, V, R, R) heatmap logits -> (B, 3) cube-frame point (the best fine cell's centre)."""
    return cell_centres(decode_cells(heatmaps, coarse, radius), heatmaps.shape[-1])


def decode_points_dense(heatmaps: torch.Tensor) -> torch.Tensor:
    """:func:`decode_points` by the dense search (tests only)."""
    return cell_centres(decode_cells_dense(heatmaps), heatmaps.shape[-1])
