"""Random sampling (paper appendix, "1. Random Sampling"): play data without prior interaction.

p1 is a random point of the object cloud inside the robot's reach, R0 a uniformly random
rotation, p2 a random manipulation position around p1 inside the valid area, and p0 the start
pose ``start_distance`` behind p1 along the approach axis. Reach, hand and approach distance
are the robot preset's (:meth:`SamplingConfig.for_robot`). Candidates whose open hand would
intersect the object cloud at p1 or on the way from p0 are rejected and redrawn. The heuristic
grasp sampler reuses :func:`complete_action` for p0 and p2, as the paper does.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.data.actions import ActionSequence
from actaim2.data.gripper import collides, points_near
from actaim2.data.object_cloud import ObjectCloud
from actaim2.profiling import timed
from actaim2.robots import HandGeometry, Reach, RobotSpec


@dataclass(frozen=True)
class SamplingConfig:
    reach: Reach  # the robot's (RobotSpec.reach)
    gripper: HandGeometry  # the robot's open hand (RobotSpec.hand)
    min_height: float = 0.02  # tcp positions stay this far above the floor (z = 0)
    manipulation_min: float = 0.1  # |p2 - p1| range (m)
    manipulation_max: float = 0.3
    approach_checks: int = 4  # hand poses checked along p0 -> p1 besides p1
    collision_tolerance: int = 3
    max_tries: int = 200

    @classmethod
    def for_robot(cls, spec: RobotSpec, **overrides) -> "SamplingConfig":
        """The sampling settings of one robot preset (its reach, hand and approach distance)."""
        if spec.reach is None or spec.hand is None:
            raise ValueError(f"robot {spec.name!r} has no {'reach' if spec.reach is None else 'hand'} geometry to sample "
                             f"actions with: add `reach` and `hand` to its YAML (see actaim2.robots.load_robot_spec)")
        return cls(reach=spec.reach, gripper=spec.hand, **overrides)

    @property
    def start_distance(self) -> float:
        """|p0 - p1| (m): the straight approach along the hand's z axis."""
        return self.gripper.approach_distance

    def reachable(self, p: np.ndarray) -> np.ndarray | bool:
        """Inside the reach shell and above the floor; ``p`` is one point or an (N, 3) array."""
        p = np.asarray(p, dtype=float)
        d = np.linalg.norm(p - np.asarray(self.reach.center), axis=-1)
        return (self.reach.min <= d) & (d <= self.reach.max) & (p[..., 2] >= self.min_height)


def approach_is_free(p1: np.ndarray, R0: np.ndarray, points: np.ndarray, config: SamplingConfig) -> bool:
    """The open hand fits at p1 and at evenly spaced poses back to p0 (straight approach)."""
    p0 = p1 - config.start_distance * R0[:, 2]
    points = points_near(points, p0, p1, float(np.linalg.norm(config.gripper.hand_extent())))
    T = np.eye(4)
    T[:3, :3] = R0
    for s in np.linspace(0.0, config.start_distance, config.approach_checks + 1):
        T[:3, 3] = p1 - s * R0[:, 2]
        if collides(config.gripper, points, T, config.collision_tolerance):
            return False
    return True


def complete_action(p1: np.ndarray, R0: np.ndarray, rng: np.random.Generator, config: SamplingConfig) -> ActionSequence | None:
    """Add a random manipulation position and the start pose; None if p0 or p2 leave the valid area."""
    p0 = p1 - config.start_distance * R0[:, 2]
    if not config.reachable(p0):
        return None
    for _ in range(20):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        p2 = p1 + rng.uniform(config.manipulation_min, config.manipulation_max) * direction
        if config.reachable(p2):
            return ActionSequence(p1=p1.copy(), p2=p2, R0=R0, start_distance=config.start_distance)
    return None


class RandomSampler:
    name = "random"

    def __init__(self, config: SamplingConfig):
        self.config = config

    @timed("sampling")
    def sample(self, cloud: ObjectCloud, rng: np.random.Generator, index: int) -> ActionSequence | None:
        """One collision-filtered random action sequence, or None if none was found."""
        reachable = np.flatnonzero(self.config.reachable(cloud.points))
        if len(reachable) == 0:
            return None
        for _ in range(self.config.max_tries):
            p1 = cloud.points[rng.choice(reachable)]
            R0 = Rotation.random(rng=rng).as_matrix()
            if not approach_is_free(p1, R0, cloud.points, self.config):
                continue
            action = complete_action(p1, R0, rng, self.config)
            if action is not None:
                return action
        return None
