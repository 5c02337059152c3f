"""Orthographic views as the policy receives them, accepted only if made the way a model expects.

``fusion_node`` stamps every ``OrthoViews`` with the digest of the :class:`PerceptionConfig` that
made it. A model is served only views of its own configuration: the digest must match, and the
layout (views, channels, resolution) must be the one the digest stands for; anything else is
refused with the reason, and the previous accepted views stay in use.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from actaim2.perception.config import PerceptionConfig
from actaim2.perception.ortho_views import VIEWS
from actaim2.policy.requests import RequestError


@dataclass(frozen=True)
class Views:
    stamp_ns: int  # the observation's stamp (ROS time, ns): keyposes predicted from these views carry it
    data: np.ndarray  # (V, C, H, W) float32, as rendered


def accept_views(stamp_ns: int, height: int, width: int, views: Sequence[str], channels: Sequence[str],
                 data: Sequence[float] | np.ndarray, digest: str, expected: PerceptionConfig) -> Views:
    """Views from the message's fields, or a RequestError saying why they cannot be used."""
    wanted = expected.digest()
    if digest != wanted:
        raise RequestError(f"views made under perception configuration {digest or '<none>'} but the checkpoint "
                           f"expects {wanted} ({expected.rig}, {expected.resolution} px, robot "
                           f"{'hidden' if expected.remove_robot_views else 'visible'}): refused")
    shape = (len(VIEWS), len(expected.channels), expected.resolution, expected.resolution)
    if list(views) != list(VIEWS) or list(channels) != list(expected.channels) or (height, width) != shape[2:]:
        raise RequestError(f"views {list(views)} x {list(channels)} at {height}x{width} do not have the layout "
                           f"of their configuration ({list(VIEWS)} x {list(expected.channels)} at {shape[2]}x{shape[3]})")
    array = np.asarray(data, dtype=np.float32)  # a message's array.array('f') is wrapped, not copied
    if array.size != np.prod(shape):
        raise RequestError(f"views carry {array.size} values, their layout needs {int(np.prod(shape))}")
    return Views(int(stamp_ns), array.reshape(shape))
