"""VGG-19's convolutional `features` stack, laid out exactly as torchvision's ``vgg19().features``.

The paper's image encoder is an ImageNet VGG-19 without its fully connected layers. torchvision
cannot be installed next to this torch build and no weights can be downloaded here, so the stack
is rebuilt with the same ``nn.Sequential`` indices (conv at 0, 2, 5, 7, 10, ...; ReLU and
MaxPool in between): a user's weight file — a full ``vgg19`` state_dict ("features.0.weight",
..., "classifier.6.bias") or a features-only one ("0.weight", ...) — loads unchanged.
"""
from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

# torchvision's configuration "E" (VGG-19): output channels of each 3x3 conv, "M" = 2x2 max pool.
VGG19_LAYERS: tuple[int | str, ...] = (
    64, 64, "M", 128, 128, "M", 256, 256, 256, 256, "M",
    512, 512, 512, 512, "M", 512, 512, 512, 512, "M",
)
IMAGENET_MEAN = (0.485, 0.456, 0.406)  # what VGG-19's ImageNet weights expect after /255
IMAGENET_STD = (0.229, 0.224, 0.225)
VGG19_OUT_CHANNELS = 512


def vgg19_features() -> nn.Sequential:
    """The 37-module stack of torchvision's ``vgg19().features`` (no batch norm), randomly initialised."""
    layers: list[nn.Module] = []
    channels = 3
    for v in VGG19_LAYERS:
        if v == "M":
            layers.append(nn.MaxPool2d(kernel_size=2, stride=2))
        else:
            layers += [nn.Conv2d(channels, int(v), kernel_size=3, padding=1), nn.ReLU(inplace=True)]
            channels = int(v)
    return nn.Sequential(*layers)


def load_vgg19_features(path: str | Path) -> nn.Sequential:
    """VGG-19 features with weights from a torchvision-format state_dict file.

    Accepts a full classifier state_dict (its ``classifier.*`` entries are ignored) or a
    features-only one; anything else (e.g. vgg19_bn, whose indices differ) is refused with the
    keys that did not match.
    """
    state = torch.load(path, map_location="cpu", weights_only=True)
    if not isinstance(state, dict):
        raise ValueError(f"{path}: expected a state_dict (dict of tensors), got {type(state).__name__}")
    if any(k.startswith("features.") for k in state):
        state = {k[len("features."):]: v for k, v in state.items() if k.startswith("features.")}
    features = vgg19_features()
    missing, unexpected = features.load_state_dict(state, strict=False)
    if missing or unexpected:
        raise ValueError(f"{path} is not a VGG-19 features state_dict: missing {missing[:4]}, unexpected {unexpected[:4]}")
    return features
