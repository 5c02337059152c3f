"""The image encoder E of the task embedding z = E(O_init) - E(O_final).

E maps every camera picture of an observation to a feature map, average-pools it onto a small
fixed grid (keeping *where* things are: a door swinging open changes the layout more than the
mean colour) and concatenates the cameras in name order.

Two backbones, one interface:
  * ``vgg19``: the paper's choice, an ImageNet VGG-19 without its fully connected layers,
    for users who have a torchvision VGG-19 weight file (``vgg.load_vgg19_features``).
  * ``autoencoder`` (project default): a small convolutional autoencoder the project trains on
    its own robot-hidden observations (``encoder_training``), no DoF labels involved. It is
    ~60x cheaper than VGG-19 on a CPU and needs no downloaded weights.

Encoder files are ``torch.save`` dicts of the spec and the state_dict, loaded with
``weights_only=True``.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from actaim2.data.trajectory import CameraImage, Observation
from actaim2.data.vgg import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    VGG19_OUT_CHANNELS,
    load_vgg19_features,
    vgg19_features,
)


@dataclass(frozen=True)
class EncoderSpec:
    kind: str  # "autoencoder" | "vgg19"
    channels: str  # "rgb" | "rgbd": what each picture contributes
    height: int  # pictures are resized to height x width before encoding
    width: int
    pool: tuple[int, int]  # feature grid kept per camera
    max_depth: float = 3.0  # metres mapped to 1.0 on the depth channel

    @property
    def in_channels(self) -> int:
        return 3 if self.channels == "rgb" else 4


AUTOENCODER_SPEC = EncoderSpec(kind="autoencoder", channels="rgbd", height=96, width=128, pool=(6, 8))
VGG19_SPEC = EncoderSpec(kind="vgg19", channels="rgb", height=240, width=320, pool=(7, 7))

AE_WIDTHS = (16, 32, 64, 64)  # conv widths, each stride 2: 96x128 -> 6x8
AE_LATENT = 8  # channels of the bottleneck map


class ConvAutoencoder(nn.Module):
    """Small RGB-D autoencoder; its ``encoder`` is the default backbone of E."""

    def __init__(self, in_channels: int = 4):
        super().__init__()
        enc: list[nn.Module] = []
        c = in_channels
        for w in AE_WIDTHS:
            enc += [nn.Conv2d(c, w, 4, stride=2, padding=1), nn.ReLU(inplace=True)]
            c = w
        enc.append(nn.Conv2d(c, AE_LATENT, 1))
        self.encoder = nn.Sequential(*enc)
        dec: list[nn.Module] = [nn.Conv2d(AE_LATENT, c, 1), nn.ReLU(inplace=True)]
        for w in list(AE_WIDTHS[:-1])[::-1] + [in_channels]:
            dec += [nn.ConvTranspose2d(c, w, 4, stride=2, padding=1), nn.ReLU(inplace=True)]
            c = w
        self.decoder = nn.Sequential(*dec[:-1])  # no ReLU on the reconstruction

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.decoder(self.encoder(x))


class ImageEncoder(nn.Module):
    """E: camera pictures -> one vector per observation."""

    def __init__(self, spec: EncoderSpec, backbone: nn.Module):
        super().__init__()
        self.spec = spec
        self.backbone = backbone
        self.register_buffer("mean", torch.tensor(IMAGENET_MEAN).view(1, 3, 1, 1))
        self.register_buffer("std", torch.tensor(IMAGENET_STD).view(1, 3, 1, 1))

    @classmethod
    def autoencoder(cls, ae: ConvAutoencoder | None = None) -> "ImageEncoder":
        return cls(AUTOENCODER_SPEC, (ae or ConvAutoencoder(AUTOENCODER_SPEC.in_channels)).encoder)

    @classmethod
    def vgg19(cls, weights: str | Path | None = None) -> "ImageEncoder":
        """VGG-19 E; ``weights`` is a torchvision vgg19 state_dict file (random weights if None)."""
        return cls(VGG19_SPEC, load_vgg19_features(weights) if weights else vgg19_features())

    @property
    def dim_per_camera(self) -> int:
        channels = VGG19_OUT_CHANNELS if self.spec.kind == "vgg19" else AE_LATENT
        return channels * self.spec.pool[0] * self.spec.pool[1]

    def preprocess(self, images: list[CameraImage]) -> torch.Tensor:
        """(N, C, H, W) network input: normalised RGB (+ depth / max_depth), resized."""
        rgb = torch.from_numpy(np.stack([im.rgb for im in images])).permute(0, 3, 1, 2).float() / 255.0
        x = (rgb - self.mean) / self.std
        if self.spec.channels == "rgbd":
            depth = torch.from_numpy(np.stack([im.depth for im in images])).unsqueeze(1)
            x = torch.cat([x, (depth / self.spec.max_depth).clamp(0.0, 1.0)], dim=1)
        return F.interpolate(x, size=(self.spec.height, self.spec.width), mode="area")

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(N, C, H, W) preprocessed pictures -> (N, dim_per_camera)."""
        return F.adaptive_avg_pool2d(self.backbone(x), self.spec.pool).flatten(1)

    @torch.no_grad()
    def encode(self, observations: list[Observation]) -> np.ndarray:
        """(len(observations), cameras * dim_per_camera): one row per observation, cameras in name order."""
        cams = sorted(observations[0])
        images = [obs[c] for obs in observations for c in cams]
        feats = self(self.preprocess(images))
        return feats.view(len(observations), -1).numpy()

    def save(self, path: str | Path) -> None:
        torch.save({"spec": asdict(self.spec), "state_dict": self.backbone.state_dict()}, path)

    @classmethod
    def load(cls, path: str | Path) -> "ImageEncoder":
        blob = torch.load(path, map_location="cpu", weights_only=True)
        d = dict(blob["spec"])
        spec = EncoderSpec(**{**d, "pool": tuple(d["pool"])})
        backbone = vgg19_features() if spec.kind == "vgg19" else ConvAutoencoder(spec.in_channels).encoder
        backbone.load_state_dict(blob["state_dict"])
        return cls(spec, backbone).eval()
