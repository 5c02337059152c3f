"""Clouds in, fused cloud and orthographic views out: the one path shared by node, CLI and training.

Order: decode -> world + crop + voxel (fusion.py) -> optional robot self-filter (self_filter.py)
-> z-buffered views (ortho_views.py). The node, ``actaim2 render``, the benchmark and
training-data preprocessing all call :meth:`Perception.process`, so views rendered for training
and views served to the policy come from the same code with the same settings.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from actaim2.perception.fusion import CameraCloud, FusedCloud, FusionConfig, fuse
from actaim2.perception.ortho_views import DEFAULT_RESOLUTION, render_views
from actaim2.perception.self_filter import RobotSelfFilter


class EmptyObservationError(ValueError):
    """The clouds held no usable point inside the workspace: nothing worth publishing."""


@dataclass(frozen=True)
class PerceptionConfig:
    fusion: FusionConfig
    resolution: int = DEFAULT_RESOLUTION
    remove_robot_fused: bool = False  # drop robot points from the fused cloud output
    remove_robot_views: bool = True  # ... and from the views (the policy is trained robot-hidden)


@dataclass(frozen=True)
class Observation:
    fused: FusedCloud  # world frame, robot removed if remove_robot_fused
    views: np.ndarray  # (len(VIEWS), len(CHANNELS), R, R) float32


class Perception:
    """Stateless apart from the self-filter's joint positions (updated with :meth:`set_joint_positions`)."""

    def __init__(self, config: PerceptionConfig, self_filter: RobotSelfFilter | None = None) -> None:
        if (config.remove_robot_fused or config.remove_robot_views) and self_filter is None:
            raise ValueError("removing the robot needs a RobotSelfFilter")
        self.config = config
        self.self_filter = self_filter

    def process(self, clouds: list[CameraCloud]) -> Observation:
        """Fuse and render; raises EmptyObservationError when no point lies in the workspace."""
        fusion = self.config.fusion
        fused = fuse(clouds, fusion)
        if len(fused.xyz) == 0:
            raise EmptyObservationError(
                f"no valid point inside the workspace (center {list(fusion.center)}, half extent {fusion.half_extent} m)"
            )
        without_robot = fused
        if self.self_filter is not None and (self.config.remove_robot_fused or self.config.remove_robot_views):
            without_robot = fused.subset(self.self_filter.keep_mask(fused.xyz))
        shown = without_robot if self.config.remove_robot_views else fused
        views = render_views(shown.xyz, shown.rgb, fusion.center, fusion.half_extent, self.config.resolution)
        return Observation(without_robot if self.config.remove_robot_fused else fused, views)
