"""The non-learned baseline of the episode runner (``keyposes:=sampler``): the four keyposes from the
heuristic grasp sampler of data collection (``actaim2.data.grasp_sampler``: DBSCAN parts,
antipodal grasps) on the fused, robot-filtered cloud. It sees no privileged state."""
from __future__ import annotations

import numpy as np
from sensor_msgs.msg import PointCloud2

from actaim2.data.grasp_sampler import HeuristicGraspSampler
from actaim2.data.object_cloud import CloudConfig, ObjectCloud, remove_support
from actaim2.data.random_sampler import SamplingConfig
from actaim2.keypose import Keypose
from actaim2.robots import load_robot_spec
from actaim2_ros.pointcloud2 import from_msg


class GraspBaseline:
    def __init__(self, center: tuple[float, float, float], half_extent: float, draws: int, robot: str):
        """``robot``: preset or robot YAML whose reach and hand decide which grasps are candidates."""
        self._sampler = HeuristicGraspSampler(CloudConfig(center=center, half_extent=half_extent),
                                              SamplingConfig.for_robot(load_robot_spec(robot)))
        self._draws = draws

    def keyposes(self, cloud: PointCloud2, rng: np.random.Generator) -> list[Keypose]:
        """INIT, REACH, GRASP, MANIPULATE on the object's points; ValueError when no grasp is found."""
        decoded = from_msg(cloud)
        valid = np.all(np.isfinite(decoded.xyz), axis=1)
        points = decoded.xyz[valid].astype(np.float64)
        colors = decoded.rgb[valid] if decoded.rgb is not None else np.zeros((len(points), 3), np.uint8)
        keep = remove_support(points, self._sampler.cloud_config, rng)
        object_cloud = ObjectCloud(points[keep], colors[keep])
        for index in range(self._draws):
            action = self._sampler.sample(object_cloud, rng, index)
            if action is not None:
                return list(action.keyposes())
        raise ValueError(f"no grasp found on {len(object_cloud.points)} object points in {self._draws} draws")
