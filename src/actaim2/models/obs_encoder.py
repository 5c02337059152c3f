"""The mode selector's condition O: robot-hidden orthographic views -> one token per view.

A small CNN trained with the selector (the paper uses a frozen VGG-19; no ImageNet weights can
be downloaded here, and RGB-XYZ-depth views are not ImageNet pictures). One convolution stack
is shared by the views; a learned per-view embedding tells them apart. Views are first
area-downsampled to ``input_resolution`` (the token needs the layout, not fine detail) and
standardised per channel with statistics measured on the training views (world XYZ sits around
the cube centre, colours in 0..1, depth in 0..2 half extents: one fixed standardisation
puts them on one scale without a perception-specific constant in the model).

A user who has torchvision VGG-19 weights can build the paper's variant with
``backbone="vgg19"`` and :meth:`ObsEncoder.load_vgg19`; the RGB channels then go through the
frozen VGG-19 stack of :mod:`actaim2.data.vgg` and are max-pooled to ``token_dim`` per view.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch
import torch.nn.functional as F
from torch import nn

from actaim2.data.vgg import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    VGG19_OUT_CHANNELS,
    load_vgg19_features,
    vgg19_features,
)


@dataclass(frozen=True)
class ObsEncoderConfig:
    views: int = 5
    in_channels: int = 8  # r, g, b, x, y, z, depth, occupancy (actaim2.perception.ortho_views.CHANNELS)
    input_resolution: int = 32  # 3.75 cm per pixel over ring5's 1.2 m cube: object layout and state, cheaply
    widths: tuple[int, ...] = (16, 32, 64)  # stride-2 convolutions: 32 -> 4 px
    token_dim: int = 64
    backbone: str = "cnn"  # "cnn" (trained here) | "vgg19" (frozen, user-supplied weights)

    def __post_init__(self) -> None:
        if self.backbone not in ("cnn", "vgg19"):
            raise ValueError(f"backbone must be 'cnn' or 'vgg19', got {self.backbone!r}")


class ObsEncoder(nn.Module):
    """(B, V, C, H, W) views -> (B, V, token_dim) tokens."""

    def __init__(self, config: ObsEncoderConfig):
        super().__init__()
        self.config = config
        self.register_buffer("channel_mean", torch.zeros(config.in_channels))
        self.register_buffer("channel_std", torch.ones(config.in_channels))
        if config.backbone == "cnn":
            layers: list[nn.Module] = []
            c = config.in_channels
            for w in config.widths:
                layers += [nn.Conv2d(c, w, 3, stride=2, padding=1), nn.GroupNorm(min(8, w), w), nn.GELU()]
                c = w
            self.backbone = nn.Sequential(*layers)
            self.head = nn.Linear(c, config.token_dim)
        else:
            self.backbone = vgg19_features().requires_grad_(False)
            self.head = nn.Linear(VGG19_OUT_CHANNELS, config.token_dim)
            self.register_buffer("rgb_mean", torch.tensor(IMAGENET_MEAN).view(1, 3, 1, 1))
            self.register_buffer("rgb_std", torch.tensor(IMAGENET_STD).view(1, 3, 1, 1))
        self.view_embedding = nn.Parameter(torch.zeros(config.views, config.token_dim))
        nn.init.normal_(self.view_embedding, std=0.02)

    @torch.no_grad()
    def fit_input_statistics(self, views: torch.Tensor) -> None:
        """Set the per-channel standardisation from training views (B, V, C, H, W); call once before training."""
        x = views.float().transpose(0, 2).reshape(views.shape[2], -1)
        self.channel_mean.copy_(x.mean(dim=1))
        self.channel_std.copy_(x.std(dim=1).clamp_min(1e-3))

    def load_vgg19(self, path: str | Path) -> None:
        """Load a torchvision VGG-19 state_dict into the frozen backbone (``backbone="vgg19"`` only)."""
        if self.config.backbone != "vgg19":
            raise ValueError("load_vgg19 needs an encoder built with backbone='vgg19'")
        self.backbone.load_state_dict(load_vgg19_features(path).state_dict())

    def forward(self, views: torch.Tensor) -> torch.Tensor:
        b, v, c, h, w = views.shape
        if v != self.config.views or c != self.config.in_channels:
            raise ValueError(f"expected views (B, {self.config.views}, {self.config.in_channels}, H, W), got {tuple(views.shape)}")
        x = views.reshape(b * v, c, h, w).float()
        r = self.config.input_resolution
        if (h, w) != (r, r):  # avg_pool2d with an integer kernel: 1.4x faster than adaptive pooling here
            x = F.avg_pool2d(x, h // r) if h == w and h % r == 0 else F.adaptive_avg_pool2d(x, (r, r))
        if self.config.backbone == "cnn":
            x = (x - self.channel_mean.view(1, -1, 1, 1)) / self.channel_std.view(1, -1, 1, 1)
            feat = self.backbone(x).mean(dim=(2, 3))
        else:
            feat = self.backbone((x[:, :3] - self.rgb_mean) / self.rgb_std).amax(dim=(2, 3))
        return self.head(feat).view(b, v, -1) + self.view_embedding
