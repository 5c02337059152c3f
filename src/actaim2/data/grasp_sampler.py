"""Heuristic grasp sampling (paper appendix, "2. Heuristic Grasping Sampling").

The object cloud is split into protruding parts (support and large faces removed, DBSCAN), a
grasp proposer scores grasps on every part, and one of the best is taken as interaction point
p1 and rotation R0; p0 and p2 follow the random sampler's rules. Biasing p1 onto handles,
knobs and buttons is what brings "grasp to open" interactions into the dataset.
"""
from __future__ import annotations

import numpy as np

from actaim2.data.actions import ActionSequence
from actaim2.data.grasp import AntipodalConfig, AntipodalGraspProposer, GraspProposer
from actaim2.data.object_cloud import CloudConfig, ObjectCloud, part_segments
from actaim2.data.random_sampler import SamplingConfig, approach_is_free, complete_action
from actaim2.profiling import timed


class HeuristicGraspSampler:
    name = "grasp"

    def __init__(self, cloud_config: CloudConfig, config: SamplingConfig, proposer: GraspProposer | None = None, top_k: int = 5):
        """``proposer`` defaults to the geometric one with the robot's hand and shoulder (from ``config``)."""
        self.cloud_config = cloud_config
        self.config = config
        self.proposer = proposer or AntipodalGraspProposer(AntipodalConfig(gripper=config.gripper, reach_center=config.reach.center))
        self.top_k = top_k  # one of the k best grasps is drawn: the best alone would repeat itself

    @timed("sampling")
    def sample(self, cloud: ObjectCloud, rng: np.random.Generator, index: int) -> ActionSequence | None:
        candidates = []
        for i, segment in enumerate(part_segments(cloud, self.cloud_config, rng)):
            candidates += self.proposer.propose(cloud, segment, i, rng)
        candidates = [c for c in candidates if self.config.reachable(c.T_world_tcp[:3, 3])]
        candidates.sort(key=lambda c: -c.score)
        best = candidates[: self.top_k]
        for k in rng.permutation(len(best)):
            T = best[k].T_world_tcp
            if not approach_is_free(T[:3, 3], T[:3, :3], cloud.points, self.config):
                continue
            action = complete_action(T[:3, 3], T[:3, :3], rng, self.config)
            if action is not None:
                return action
        return None
