"""The action predictor P(a | O, eps): an RVT-style multi-view transformer (paper, action predictor).

Input: the five orthographic views as :mod:`actaim2.perception.ortho_views` renders them (colour,
cube-frame xyz, depth as a fraction of the cube side, occupancy), the interaction mode eps and
the proprioception (gripper closed, phase one-hot: :func:`proprio_features`).

Network, as RVT's MVT:
  1. Two pixel-location channels (column, row in [-1, 1]) are appended to every view; RVT's
     renderer does not draw them either, the network adds them.
  2. Patches of ``patch`` x ``patch`` px become tokens by one linear map (what RVT's strided
     convolution computes; as a matrix product its backward pass ran 5x faster here) plus a
     learned position embedding per view and patch.
  3. eps and the proprioception, through a small MLP, are *added to every token*: each token
     knows the mode and the phase from the first layer on.
  4. ``layers_within`` blocks attend within each view, then ``layers_across`` blocks over the
     tokens of all views (RVT's ``self_cross_ver=1``).
  5. Translation: per view, each token's features map linearly to its patch's ``patch^2`` pixel
     logits, put in place by pixel shuffle - no full-resolution convolution (those cost more
     than the whole transformer on a CPU).
  6. Rotation (3 x 72 Euler bins) and gripper (2) logits come from pooled features: per view the
     maximum over tokens and the heatmap-weighted mean of tokens (RVT-1's pooling; the heatmap
     is detached, so only the translation loss shapes it), concatenated over views with the
     conditioning features.

:func:`decode_action` turns the outputs into a keypose: the 3-D point by the coarse-to-fine
cube-grid search, the rotation from the most likely bins, the gripper from its argmax.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from actaim2.data.trajectory import PHASES
from actaim2.models.rotation_bins import ROTATION_BINS, bins_to_quat
from actaim2.models.view_geometry import CubePlacement, decode_points
from actaim2.perception.ortho_views import CHANNELS, DEFAULT_RESOLUTION, VIEWS

PROPRIO_DIM = 1 + len(PHASES)  # gripper closed + phase one-hot
PIXEL_CHANNELS = 2  # column and row location, appended by the network


@dataclass(frozen=True)
class PredictorConfig:
    """Sizes of :class:`ActionPredictor`; the defaults are the CPU configuration.

    ``embedding_dim`` is the size of eps, i.e. of the dataset's task embeddings z (it depends on
    the encoder E and the camera rig), so it has no default.
    """

    embedding_dim: int
    image_size: int = DEFAULT_RESOLUTION
    patch: int = 16
    width: int = 128
    layers_within: int = 2
    layers_across: int = 2
    heads: int = 4
    mlp_ratio: int = 4
    rotation_bins: int = ROTATION_BINS
    proprio_dim: int = PROPRIO_DIM
    in_channels: int = len(CHANNELS)
    views: int = len(VIEWS)
    # Dropout (attention weights and residual branches). 0 on the CPU: attention-weight dropout
    # rules out the fused attention kernel and made a training step 40% slower here; scene
    # augmentation regularises instead. RVT's 0.1 in rvt_size().
    dropout: float = 0.0

    def __post_init__(self) -> None:
        if self.image_size % self.patch:
            raise ValueError(f"patch {self.patch} must divide image_size {self.image_size}")
        if self.width % self.heads:
            raise ValueError(f"heads {self.heads} must divide width {self.width}")

    @classmethod
    def rvt_size(cls, embedding_dim: int, image_size: int = 224, **overrides) -> "PredictorConfig":
        """RVT's size for a GPU: 8 layers (4 within-view + 4 across), width 512, 8 heads, dropout 0.1."""
        fields = dict(image_size=image_size, patch=16, width=512, layers_within=4, layers_across=4, heads=8, dropout=0.1)
        return cls(embedding_dim=embedding_dim, **{**fields, **overrides})

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, d: dict) -> "PredictorConfig":
        return cls(**d)


class PredictorOutput(NamedTuple):
    heatmaps: torch.Tensor  # (B, V, H, W) translation logits, a distribution over each view's pixels
    rotation: torch.Tensor  # (B, 3, bins) Euler-bin logits (rotation_bins.EULER_SEQUENCE order)
    gripper: torch.Tensor  # (B, 2) logits of [open, closed]


class DecodedAction(NamedTuple):
    position: torch.Tensor  # (B, 3) world metres
    quat_xyzw: torch.Tensor  # (B, 4)
    gripper_closed: torch.Tensor  # (B,) bool


def proprio_features(gripper_closed: torch.Tensor, phase: torch.Tensor) -> torch.Tensor:
    """(B,) gripper state (bool or 0/1) and (B,) phase ids 0..3 -> (B, PROPRIO_DIM) float."""
    one_hot = F.one_hot(phase.long(), len(PHASES)).float()
    return torch.cat([gripper_closed.float()[:, None], one_hot], dim=1)


def _block(c: PredictorConfig) -> nn.TransformerEncoderLayer:
    return nn.TransformerEncoderLayer(
        c.width, c.heads, c.width * c.mlp_ratio, c.dropout, activation="gelu", batch_first=True, norm_first=True
    )


class ActionPredictor(nn.Module):
    """P(a | O, eps): views + eps + proprioception -> heatmaps, rotation bins, gripper logits."""

    def __init__(self, config: PredictorConfig):
        super().__init__()
        c = self.config = config
        self.grid = c.image_size // c.patch
        tokens_per_view = self.grid * self.grid
        self.patch_embed = nn.Linear((c.in_channels + PIXEL_CHANNELS) * c.patch * c.patch, c.width)
        self.position = nn.Parameter(torch.randn(1, c.views, tokens_per_view, c.width) * 0.02)
        self.condition = nn.Sequential(
            nn.Linear(c.embedding_dim + c.proprio_dim, c.width), nn.GELU(), nn.Linear(c.width, c.width)
        )
        self.within = nn.ModuleList(_block(c) for _ in range(c.layers_within))
        self.across = nn.ModuleList(_block(c) for _ in range(c.layers_across))
        self.norm = nn.LayerNorm(c.width)
        self.heatmap_head = nn.Linear(c.width, c.patch * c.patch)
        self.action_head = nn.Sequential(
            nn.Linear(c.views * 2 * c.width + c.width, c.width * 2),
            nn.GELU(),
            nn.Dropout(c.dropout),
            nn.Linear(c.width * 2, 3 * c.rotation_bins + 2),
        )
        line = torch.linspace(-1.0, 1.0, c.image_size)
        rows, cols = torch.meshgrid(line, line, indexing="ij")
        self.register_buffer("pixel_location", torch.stack([cols, rows]), persistent=False)

    def forward(self, views: torch.Tensor, eps: torch.Tensor, proprio: torch.Tensor) -> PredictorOutput:
        """views (B, V, C, H, W) as rendered; eps (B, embedding_dim); proprio (B, proprio_dim)."""
        c = self.config
        b, v, _, h, w = views.shape
        if (v, h, w) != (c.views, c.image_size, c.image_size):
            raise ValueError(f"views of shape {tuple(views.shape)}, expected (B, {c.views}, C, {c.image_size}, {c.image_size})")
        x = torch.cat([views.reshape(b * v, -1, h, w), self.pixel_location.expand(b * v, -1, -1, -1)], dim=1)
        g, p = self.grid, c.patch
        patches = x.reshape(b, v, -1, g, p, g, p).permute(0, 1, 3, 5, 2, 4, 6).reshape(b, v, g * g, -1)
        tokens = self.patch_embed(patches)  # (B, V, N, D)
        cond = self.condition(torch.cat([eps, proprio], dim=1))  # (B, D)
        tokens = tokens + self.position + cond[:, None, None, :]
        n = tokens.shape[2]
        x = tokens.reshape(b * v, n, c.width)
        for block in self.within:
            x = block(x)
        x = x.reshape(b, v * n, c.width)
        for block in self.across:
            x = block(x)
        features = self.norm(x).reshape(b, v, n, c.width)

        # Translation: token -> its patch's pixel logits; pixel shuffle lays patches out (B*V, 1, H, W).
        logits = self.heatmap_head(features).reshape(b * v, self.grid, self.grid, c.patch * c.patch)
        heatmaps = F.pixel_shuffle(logits.permute(0, 3, 1, 2), c.patch).reshape(b, v, h, w)

        # Rotation and gripper from features pooled per view: max, and the mean under the heatmap.
        probs = torch.softmax(heatmaps.detach().reshape(b, v, -1), dim=-1).reshape(b, v, self.grid, c.patch, self.grid, c.patch)
        weights = probs.sum(dim=(3, 5)).reshape(b, v, n, 1)  # probability mass of each patch
        pooled = torch.cat([features.amax(dim=2), (features * weights).sum(dim=2)], dim=-1).reshape(b, -1)
        out = self.action_head(torch.cat([pooled, cond], dim=1))
        rotation = out[:, : 3 * c.rotation_bins].reshape(b, 3, c.rotation_bins)
        return PredictorOutput(heatmaps, rotation, out[:, 3 * c.rotation_bins :])

    def parameter_count(self) -> int:
        return sum(p.numel() for p in self.parameters())


@torch.no_grad()
def decode_action(out: PredictorOutput, placement: CubePlacement) -> DecodedAction:
    """The keypose each batch row predicts: position (world), quaternion (x, y, z, w), gripper."""
    position = placement.to_world(decode_points(out.heatmaps))
    bins = out.rotation.argmax(dim=-1).cpu().numpy()
    quat = torch.from_numpy(bins_to_quat(bins, out.rotation.shape[-1]).astype(np.float32)).to(position.device)
    return DecodedAction(position, quat, out.gripper.argmax(dim=-1) == 1)
