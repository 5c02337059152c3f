"""The action predictor P(a | O, eps): an RVT-style multi-view transformer (paper, action predictor).

Input: the five orthographic views as :mod:`actaim2.perception.ortho_views` renders them (colour,
cube-frame xyz, depth as a fraction of the cube side, occupancy), the interaction mode eps and
the proprioception (gripper closed, phase one-hot: :func:`proprio_features`).

Input ablations (the paper's appendix "less visual information"): ``PredictorConfig.inputs``
names the input groups the network reads (:data:`INPUT_GROUPS`: rgb, xyz, depth with its
occupancy mask, uv = the pixel-location channels) and ``PredictorConfig.view`` one view to read
instead of all five. The network is always *given* the full rendered views and picks its inputs
itself, so training, augmentation, caching and serving feed every checkpoint the same views and
each reads what its JSON says. With one view the cube-grid re-projection has nothing to
triangulate with (every cell on the pixel's ray scores the same), so a single-view predictor
also outputs logits over the R depth cells along that view's ray (:func:`decode_action`).

Network, as RVT's MVT:
  1. Two pixel-location channels (column, row in [-1, 1]) are appended to every view; RVT's
     renderer does not draw them either, the network adds them.
  2. Patches of ``patch`` x ``patch`` px become tokens by one linear map (what RVT's strided
     convolution computes; as a matrix product its backward pass ran 5x faster here) plus a
     learned position embedding per view and patch.
  3. eps and the proprioception, through a small MLP, are *added to every token*: each token
     knows the mode and the phase from the first layer on. With ``PredictorConfig.conditioning``
     ``film`` they also scale and shift every token before each block (FiLM, Perez et al. 2018).
     Why: an added vector shifts all tokens alike, so choosing *which* part to reach by the mode
     takes the blocks' MLPs to multiply it with each token's content; FiLM multiplies directly.
     Its layers start at zero (the identity), so a predictor continued from an ``add`` one starts
     as that one. With ``query`` the conditioning instead scores every patch at the output: a
     projection of it dotted with a projection of each token's final features is added to that
     patch's pixel logits (the product of a language query and pixel features by which CLIPort
     and PerAct pick *where* an instruction points). Why: a mode names which part to grasp, and
     with ``add`` the heatmap head is linear in features that carry the mode alike for every
     token; the product makes a patch's score depend on mode and patch content together. Its
     query projection starts at zero, so a predictor continued from an ``add`` one starts as that one.
  4. ``layers_within`` blocks attend within each view, then ``layers_across`` blocks over the
     tokens of all views (RVT's ``self_cross_ver=1``).
  5. Translation: per view, each token's features map linearly to its patch's ``patch^2`` pixel
     logits, put in place by pixel shuffle - no full-resolution convolution (those cost more
     than the whole transformer on a CPU).
  6. Rotation (3 x 72 Euler bins) and gripper (2) logits - and a single-view predictor's depth
     logits - come from pooled features: per view the maximum over tokens and the features at
     the action's location, concatenated over views with the conditioning features. The
     location is ``PredictorConfig.rotation_pooling``'s:
       - ``heatmap`` (RVT-1): the mean of tokens under the predicted heatmap (detached, so only
         the translation loss shapes it);
       - ``point`` (RVT-2): the token whose patch holds the point, the demonstration's point
         while training (``forward(..., point=)``) and the predicted one otherwise. Why: with
         RVT-1's pooling the rotation head learns from features wherever the heatmap is, and
         the heatmap of an under-fitted predictor is centimetres off; the rotation of a grasp
         depends on the geometry at the grasp point.

:func:`decode_action` turns the outputs into a keypose: the 3-D point by the coarse-to-fine
cube-grid search (single view: the heatmap's pixel at the most likely depth cell), the rotation
from the most likely bins, the gripper from its argmax.
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
from actaim2.models.view_geometry import (
    CubePlacement,
    decode_points,
    decode_points_in_view,
    project_cube,
    smoothed_log_probs,
)
from actaim2.perception.ortho_views import CHANNELS, DEFAULT_RESOLUTION, VIEWS

PROPRIO_DIM = 1 + len(PHASES)  # gripper closed + phase one-hot
PIXEL_CHANNELS = 2  # column and row location, appended by the network
ALL_VIEWS = "all"
# Input groups a predictor can read. Occupancy goes with depth: it is the depth measurement's
# validity mask (an empty pixel's depth is the far face), what an RGB-D camera's depth also gives.
INPUT_GROUPS: dict[str, tuple[str, ...]] = {"rgb": ("r", "g", "b"), "xyz": ("x", "y", "z"),
                                            "depth": ("depth", "occupancy"), "uv": ()}
ROTATION_POOLING = ("heatmap", "point")
CONDITIONING = ("add", "film", "query")
# Parameter-name prefixes of the layers only "film" / "query" predictors have: a predictor continued from an
# "add" one gets them freshly initialised, and TrainConfig.conditioning_lr_scale trains them at their own rate.
CONDITIONING_LAYERS = ("film.", "query.", "key.")


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
    channel_names: tuple[str, ...] = CHANNELS  # the in_channels rendered channels, in order (perception config's)
    inputs: tuple[str, ...] = tuple(INPUT_GROUPS)  # input groups read (ablation: e.g. depth + uv)
    view: str = ALL_VIEWS  # "all", or the one view read (a name in ortho_views.VIEWS; ablation)
    # Dropout (attention weights and residual branches). 0 on the CPU: attention-weight dropout
    # rules out the fused attention kernel and made a training step 40% slower here; scene
    # augmentation regularises instead. RVT's 0.1 in rvt_size().
    dropout: float = 0.0
    # Where the rotation/gripper head reads its per-view features (item 6 of the module
    # docstring): "heatmap" (RVT-1; checkpoints saved before the field existed) or "point" (RVT-2).
    rotation_pooling: str = "heatmap"
    # How eps and the proprioception reach the tokens (item 3 of the module docstring): "add" (one
    # vector added at the input; checkpoints saved before the field existed), "film" (also a
    # scale and shift before every block) or "query" (also a per-patch heatmap score, the product
    # of the conditioning and the patch's features).
    conditioning: str = "add"
    # Gaussian blur (pixels) of each view's probabilities before the point is decoded (view_geometry's
    # decode_points says why); 0: RVT's plain argmax (checkpoints saved before the field existed).
    # A serving choice, not a trained one: the same weights decode either way.
    decode_sigma_px: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "channel_names", tuple(self.channel_names))
        object.__setattr__(self, "inputs", tuple(self.inputs))
        if self.image_size % self.patch:
            raise ValueError(f"patch {self.patch} must divide image_size {self.image_size}")
        if self.width % self.heads:
            raise ValueError(f"heads {self.heads} must divide width {self.width}")
        if len(self.channel_names) != self.in_channels or not set(self.channel_names) <= set(CHANNELS):
            raise ValueError(f"channel_names {list(self.channel_names)} must name the {self.in_channels} rendered channels "
                             f"(names from {list(CHANNELS)})")
        if not self.inputs or not set(self.inputs) <= set(INPUT_GROUPS) or len(set(self.inputs)) != len(self.inputs):
            raise ValueError(f"inputs must be distinct groups from {list(INPUT_GROUPS)}, got {list(self.inputs)}")
        if not self.read_channels:
            raise ValueError(f"inputs {list(self.inputs)} select none of the rendered channels {list(self.channel_names)}")
        if self.view != ALL_VIEWS and (self.view not in VIEWS or self.views != len(VIEWS)):
            raise ValueError(f"view must be {ALL_VIEWS!r} or one of {list(VIEWS)} (of five rendered views), got {self.view!r}")
        if self.rotation_pooling not in ROTATION_POOLING:
            raise ValueError(f"rotation_pooling must be one of {list(ROTATION_POOLING)}, got {self.rotation_pooling!r}")
        if self.conditioning not in CONDITIONING:
            raise ValueError(f"conditioning must be one of {list(CONDITIONING)}, got {self.conditioning!r}")
        if not 0.0 <= self.decode_sigma_px <= self.image_size / 8:
            raise ValueError(f"decode_sigma_px must lie in [0, {self.image_size / 8:g}] px, got {self.decode_sigma_px}")

    @property
    def read_channels(self) -> tuple[int, ...]:
        """Indices of the rendered channels the network reads (the groups of ``inputs``)."""
        wanted = {name for group in self.inputs for name in INPUT_GROUPS[group]}
        return tuple(i for i, name in enumerate(self.channel_names) if name in wanted)

    @property
    def view_index(self) -> int | None:
        """The one view read, as an index into ortho_views.VIEWS; None when all are read."""
        return None if self.view == ALL_VIEWS else VIEWS.index(self.view)

    @property
    def read_views(self) -> int:
        return self.views if self.view_index is None else 1

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
    heatmaps: torch.Tensor  # (B, V, H, W) translation logits over each read view's pixels (V = 1: single view)
    rotation: torch.Tensor  # (B, 3, bins) Euler-bin logits (rotation_bins.EULER_SEQUENCE order)
    gripper: torch.Tensor  # (B, 2) logits of [open, closed]
    depth: torch.Tensor | None = None  # (B, H) single view only: logits over the depth cells along its ray


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
        self.uses_uv = "uv" in c.inputs
        read = len(c.read_channels) + (PIXEL_CHANNELS if self.uses_uv else 0)
        self.patch_embed = nn.Linear(read * c.patch * c.patch, c.width)
        self.position = nn.Parameter(torch.randn(1, c.read_views, tokens_per_view, c.width) * 0.02)
        self.condition = nn.Sequential(
            nn.Linear(c.embedding_dim + c.proprio_dim, c.width), nn.GELU(), nn.Linear(c.width, c.width)
        )
        self.within = nn.ModuleList(_block(c) for _ in range(c.layers_within))
        self.across = nn.ModuleList(_block(c) for _ in range(c.layers_across))
        self.film = nn.ModuleList(nn.Linear(c.width, 2 * c.width) for _ in range(c.layers_within + c.layers_across)) \
            if c.conditioning == "film" else None
        for layer in self.film or ():  # scale 1, shift 0: the identity until training moves them
            nn.init.zeros_(layer.weight)
            nn.init.zeros_(layer.bias)
        self.query = nn.Linear(c.width, c.width) if c.conditioning == "query" else None
        self.key = nn.Linear(c.width, c.width, bias=False) if c.conditioning == "query" else None
        if self.query is not None:  # no score until training moves it: a continued "add" predictor's outputs
            nn.init.zeros_(self.query.weight)
            nn.init.zeros_(self.query.bias)
        self.norm = nn.LayerNorm(c.width)
        self.heatmap_head = nn.Linear(c.width, c.patch * c.patch)
        self.depth_cells = 0 if c.view_index is None else c.image_size
        self.action_head = nn.Sequential(
            nn.Linear(c.read_views * 2 * c.width + c.width, c.width * 2),
            nn.GELU(),
            nn.Dropout(c.dropout),
            nn.Linear(c.width * 2, 3 * c.rotation_bins + 2 + self.depth_cells),
        )
        # Index tensors only where the network reads a subset (the full default indexes nothing).
        self.register_buffer("channel_index", torch.tensor(c.read_channels) if len(c.read_channels) < c.in_channels
                             else None, persistent=False)
        # RVT's pixel-location channels (u, v in [-1, 1]) in patches like the views' (N, 2 P^2):
        # the same for every view and batch row, so their share of the patch embedding is one
        # (N, 2 P^2) x (2 P^2, D) product per forward instead of two more channels on every view.
        line = torch.linspace(-1.0, 1.0, c.image_size)
        rows, cols = torch.meshgrid(line, line, indexing="ij")
        g, p = self.grid, c.patch
        uv = torch.stack([cols, rows]).reshape(PIXEL_CHANNELS, g, p, g, p)
        uv_patches = uv.permute(1, 3, 0, 2, 4).reshape(g * g, -1)
        self.register_buffer("uv_patches", uv_patches, persistent=False)

    def forward(self, views: torch.Tensor, eps: torch.Tensor, proprio: torch.Tensor,
                point: torch.Tensor | None = None) -> PredictorOutput:
        """views (B, V, C, H, W) as rendered (all of them); eps (B, embedding_dim); proprio (B, proprio_dim).

        The network reads only the channels of ``config.inputs`` of ``config.view``: the rest of
        ``views`` does not reach any output. ``point``: (B, 3) cube-frame position of the
        demonstrated keypose, given while training; with ``rotation_pooling="point"`` the rotation
        and gripper head read the features there instead of at the predicted point (teacher forcing,
        RVT-2). RVT-1's pooling does not use it.
        """
        c = self.config
        b, v, _, h, w = views.shape
        if (v, h, w) != (c.views, c.image_size, c.image_size):
            raise ValueError(f"views of shape {tuple(views.shape)}, expected (B, {c.views}, C, {c.image_size}, {c.image_size})")
        if c.view_index is not None:
            views, v = views[:, c.view_index : c.view_index + 1], 1
        if self.channel_index is not None:
            views = views.index_select(2, self.channel_index)
        g, p = self.grid, c.patch
        patches = views.reshape(b, v, -1, g, p, g, p).permute(0, 1, 3, 5, 2, 4, 6)
        patches = patches.reshape(b, v, g * g, -1)
        if self.uses_uv:  # the embedding's columns: the views' channels, then the pixel locations'
            weight = self.patch_embed.weight
            tokens = F.linear(patches, weight[:, : patches.shape[-1]], self.patch_embed.bias) \
                + F.linear(self.uv_patches, weight[:, patches.shape[-1] :])
        else:
            tokens = self.patch_embed(patches)  # (B, V, N, D)
        cond = self.condition(torch.cat([eps, proprio], dim=1))  # (B, D)
        tokens = tokens + self.position + cond[:, None, None, :]
        n = tokens.shape[2]
        x = tokens.reshape(b * v, n, c.width)
        for i, block in enumerate(self.within):
            x = block(self._modulate(x, cond.repeat_interleave(v, dim=0), i))
        x = x.reshape(b, v * n, c.width)
        for i, block in enumerate(self.across):
            x = block(self._modulate(x, cond, c.layers_within + i))
        features = self.norm(x).reshape(b, v, n, c.width)

        # Translation: token -> its patch's pixel logits; pixel shuffle lays patches out (B*V, 1, H, W).
        logits = self.heatmap_head(features) + self._mode_score(features, cond)
        logits = logits.reshape(b * v, self.grid, self.grid, c.patch * c.patch)
        heatmaps = F.pixel_shuffle(logits.permute(0, 3, 1, 2), c.patch).reshape(b, v, h, w)

        # Rotation and gripper from features pooled per view: max, and the features at the action.
        pooled = torch.cat([features.amax(dim=2), self._at_action(features, heatmaps, point)], dim=-1).reshape(b, -1)
        out = self.action_head(torch.cat([pooled, cond], dim=1))
        rotation = out[:, : 3 * c.rotation_bins].reshape(b, 3, c.rotation_bins)
        gripper = out[:, 3 * c.rotation_bins : 3 * c.rotation_bins + 2]
        depth = out[:, 3 * c.rotation_bins + 2 :] if self.depth_cells else None
        return PredictorOutput(heatmaps, rotation, gripper, depth)

    def _modulate(self, x: torch.Tensor, cond: torch.Tensor, layer: int) -> torch.Tensor:
        """FiLM before block ``layer``: x (R, N, D) scaled and shifted per row by cond (R, D); x itself without FiLM."""
        if self.film is None:
            return x
        scale, shift = self.film[layer](cond).unsqueeze(1).chunk(2, dim=-1)
        return x * (1.0 + scale) + shift

    def _mode_score(self, features: torch.Tensor, cond: torch.Tensor) -> torch.Tensor | float:
        """(B, V, N, 1) the conditioning's score of every patch, added to all its pixel logits; 0 without ``query``."""
        if self.query is None:
            return 0.0
        q = self.query(cond)[:, None, :, None]  # (B, 1, D, 1)
        return torch.matmul(self.key(features), q) / self.config.width ** 0.5

    def _at_action(self, features: torch.Tensor, heatmaps: torch.Tensor, point: torch.Tensor | None) -> torch.Tensor:
        """(B, V, D) per-view features at the action's location (``config.rotation_pooling``)."""
        c = self.config
        b, v, n, d = features.shape
        if c.rotation_pooling == "heatmap":
            probs = torch.softmax(heatmaps.detach().reshape(b, v, -1), dim=-1).reshape(b, v, self.grid, c.patch, self.grid, c.patch)
            weights = probs.sum(dim=(3, 5)).reshape(b, v, n, 1)  # probability mass of each patch
            return (features * weights).sum(dim=2)
        with torch.no_grad():
            if point is not None:
                uv = project_cube(point, c.image_size)  # (B, 5, 2): every rendered view
                uv = uv if c.view_index is None else uv[:, c.view_index : c.view_index + 1]
            elif c.view_index is None:  # the decoded point seen from each view, as decode_action finds it
                uv = project_cube(decode_points(heatmaps, c.decode_sigma_px), c.image_size)
            else:  # one view: the point's pixel is the heatmap's most likely one, whatever its depth
                pixel = smoothed_log_probs(heatmaps, c.decode_sigma_px).argmax(dim=-1, keepdim=True)
                uv = torch.stack([pixel % c.image_size, pixel // c.image_size], dim=-1).float() + 0.5
            cell = (uv / c.patch).floor().long().clamp_(0, self.grid - 1)
            token = cell[..., 1] * self.grid + cell[..., 0]  # (B, V): patches are laid out row-major
        return features.gather(2, token[..., None, None].expand(b, v, 1, d)).squeeze(2)

    def parameter_count(self) -> int:
        return sum(p.numel() for p in self.parameters())


@torch.no_grad()
def decode_action(out: PredictorOutput, placement: CubePlacement, view: int | None = None,
                  sigma_px: float = 0.0) -> DecodedAction:
    """The keypose each batch row predicts: position (world), quaternion (x, y, z, w), gripper.

    ``view``: the predictor's ``config.view_index`` (None: all five views). A single-view
    output's point is its heatmap's most likely pixel at its most likely depth cell.
    ``sigma_px``: the predictor's ``config.decode_sigma_px`` (the heatmaps' blur before decoding).
    """
    if (view is None) != (out.depth is None):
        raise ValueError("a single-view output needs its view index (config.view_index), a five-view one none")
    cube = decode_points(out.heatmaps, sigma_px) if view is None \
        else decode_points_in_view(out.heatmaps[:, 0], out.depth, view, sigma_px)
    position = placement.to_world(cube)
    bins = out.rotation.argmax(dim=-1).cpu().numpy()
    quat = torch.from_numpy(bins_to_quat(bins, out.rotation.shape[-1]).astype(np.float32)).to(position.device)
    return DecodedAction(position, quat, out.gripper.argmax(dim=-1) == 1)
