"""Orthographic views of the simulated scene, made exactly as the training views were.

Training renders its views from the stored camera pictures (``actaim2.data.torch_dataset``):
back-projected depth, fused, the robot removed by the self-filter at the joint positions of the
picture, splatted by :class:`actaim2.perception.pipeline.Perception`. Evaluation takes the
pictures from the running simulator and goes through the same steps, so a checkpoint is served
the views it was trained on (``fusion_node`` does the same on the ROS side).
"""
from __future__ import annotations

import numpy as np

from actaim2.data.collect import from_sim
from actaim2.data.object_cloud import back_project
from actaim2.data.trajectory import Observation
from actaim2.perception.config import PerceptionConfig
from actaim2.perception.extrinsic_refinement import ExtrinsicRefiner
from actaim2.perception.fusion import CameraCloud
from actaim2.perception.pipeline import Perception
from actaim2.perception.self_filter import RobotSelfFilter
from actaim2.robots import RobotSpec
from actaim2.sim.env import SimEnv


class ViewMaker:
    """Views of one perception configuration (robot hidden when it says so); with ``refiner``, each picture's
    extrinsic is first refined from the robot in it (a picture without the robot keeps its own: the fit is
    refused), as ``bag2dataset`` and ``fusion_node`` refine a real rig's."""

    def __init__(self, config: PerceptionConfig, spec: RobotSpec, refiner: ExtrinsicRefiner | None = None):
        self_filter = RobotSelfFilter(spec, config.self_filter_margin) if config.remove_robot_views else None
        self.perception = Perception(config, self_filter)
        self.refiner = refiner

    def views(self, pictures: Observation, env: SimEnv) -> np.ndarray:
        """(V, C, R, R) float32 views of ``pictures`` taken with the robot at its current joint positions."""
        names, positions, _ = env.joint_state()
        joints = dict(zip(names, (float(p) for p in positions)))
        if self.perception.self_filter is not None:
            self.perception.self_filter.set_joint_positions(list(joints), list(joints.values()))
        clouds = []
        for camera in sorted(pictures):
            picture = pictures[camera]
            points, T = back_project(picture), picture.T_world_optical
            if self.refiner is not None:
                T = self.refiner.refine(points.reshape(*picture.depth.shape, 3), T, joints).T_world_optical
            clouds.append(CameraCloud(points, picture.rgb.reshape(-1, 3), T))
        return self.perception.process(clouds).views


def pictures(env: SimEnv, with_robot: bool) -> Observation:
    """The rig's camera pictures now, as data collection stores them."""
    return from_sim(env.observe(with_robot=with_robot))
