"""Clouds in, fused cloud and orthographic views out: the one path shared by node, CLI and training.

Order: decode -> world + crop + voxel (fusion.py) -> optional robot self-filter (self_filter.py)
-> splatted views (ortho_views.py), every setting from one :class:`PerceptionConfig`. The node,
``actaim2 render``, the benchmark and training-data preprocessing all go through
:class:`Perception`, so views rendered for training and views served to the policy come from the
same code with the same settings. The steps are separate methods because the node publishes
the fused cloud as soon as clouds arrive, while the robot-hidden views wait for joint states.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from actaim2.perception.config import PerceptionConfig
from actaim2.perception.fusion import CameraCloud, FusedCloud, fuse
from actaim2.perception.ortho_views import CHANNELS, render_views
from actaim2.perception.self_filter import RobotSelfFilter


class EmptyObservationError(ValueError):
    """The clouds held no usable point inside the workspace: nothing worth publishing."""


@dataclass(frozen=True)
class Observation:
    fused: FusedCloud  # world frame, every point in the cube (robot included)
    views: np.ndarray  # (len(VIEWS), len(config.channels), R, R) float32, robot hidden if remove_robot_views


class Perception:
    """Stateless apart from the self-filter's joint positions (set on ``self_filter`` by the caller)."""

    def __init__(self, config: PerceptionConfig, self_filter: RobotSelfFilter | None = None) -> None:
        if config.remove_robot_views and self_filter is None:
            raise ValueError("robot-hidden views (remove_robot_views) need a RobotSelfFilter")
        self.config = config
        self.self_filter = self_filter
        self._channels = [CHANNELS.index(c) for c in config.channels]  # the config's subset, in its order

    def fuse(self, clouds: list[CameraCloud]) -> FusedCloud:
        """World-frame cloud in the cube; raises EmptyObservationError when no point lies in it."""
        fused = fuse(clouds, self.config.fusion)
        if len(fused.xyz) == 0:
            raise EmptyObservationError(
                f"no valid point inside the workspace (center {list(self.config.center)}, half extent {self.config.half_extent} m)"
            )
        return fused

    def without_robot(self, fused: FusedCloud) -> FusedCloud:
        """The points the self-filter keeps at its current joint positions."""
        if self.self_filter is None:
            raise ValueError("removing the robot needs a RobotSelfFilter")
        return fused.subset(self.self_filter.keep_mask(fused.xyz))

    def render(self, cloud: FusedCloud) -> np.ndarray:
        """Views of ``cloud`` as it is (hide the robot first with :meth:`without_robot`)."""
        c = self.config
        views = render_views(cloud.xyz, cloud.rgb, c.center, c.half_extent, c.resolution, c.splat_radius, c.splat_depth_tolerance)
        return views if c.channels == CHANNELS else views[:, self._channels]

    def process(self, clouds: list[CameraCloud]) -> Observation:
        """Fuse and render (robot hidden from the views if configured): training and tools."""
        fused = self.fuse(clouds)
        return Observation(fused, self.render(self.without_robot(fused) if self.config.remove_robot_views else fused))
