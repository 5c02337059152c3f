"""Grasp proposers: where a parallel gripper can close on a part of the object cloud.

The paper runs a pre-trained GraspNet on each segment. No GraspNet weights can be had here, so
the default is a geometric antipodal proposer in the spirit of Grasp Pose Detection (ten Pas
et al.): hands are placed around sampled surface points, oriented from the local normal and the
part's long axis, centred on what lies between the fingers, and kept when the open hand does
not intersect the cloud and the points the fingers meet first face the fingers (within a
friction cone). A learned proposer only has to implement :class:`GraspProposer`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.data.gripper import collides, points_in_tcp, tcp_pose
from actaim2.data.object_cloud import ObjectCloud, estimate_normals
from actaim2.robots import HandGeometry


@dataclass
class GraspCandidate:
    T_world_tcp: np.ndarray  # 4x4, canonical tcp (z approach, y closing)
    width: float  # m between the first contacts
    score: float  # higher is better; comparable within one proposer
    segment: int  # index of the segment it was proposed on


class GraspProposer(Protocol):
    """Anything that turns a segment of the object cloud into scored grasps."""

    def propose(self, cloud: ObjectCloud, segment: np.ndarray, segment_id: int, rng: np.random.Generator) -> list[GraspCandidate]:
        """Grasps on ``cloud.points[segment]``; the whole cloud is given for collision checks."""


@dataclass(frozen=True)
class AntipodalConfig:
    gripper: HandGeometry  # the robot's open hand
    reach_center: tuple[float, float, float]  # the robot's shoulder: hands prefer to come from the robot
    anchors: int = 16  # surface points hands are placed around, per segment
    approach_tilts_deg: tuple[float, ...] = (-45.0, -22.5, 0.0, 22.5, 45.0)  # about the part's long axis
    depth: float = 0.015  # m the fingertips go past the anchor surface
    friction_deg: float = 30.0  # contact normals within this of the closing axis count as antipodal
    min_quality: float = 0.6  # mean |cos| of both sides' best contact normal with the closing axis
    neighbourhood: float = 0.02  # m radius for the local long axis
    normal_radius: float = 0.012  # m radius of the neighbourhood a surface normal is fitted to
    collision_tolerance: int = 2
    min_points_between: int = 3


class AntipodalGraspProposer:
    """Geometric antipodal grasps, scored by contact-normal agreement and approach direction."""

    def __init__(self, config: AntipodalConfig):
        self.config = config

    def propose(self, cloud: ObjectCloud, segment: np.ndarray, segment_id: int, rng: np.random.Generator) -> list[GraspCandidate]:
        cfg = self.config
        if len(segment) < 3:
            return []
        # Only points a hand placed on this segment can touch matter for collisions and contacts.
        seg_pts = cloud.points[segment]
        centre = seg_pts.mean(0)
        reach = np.linalg.norm(seg_pts - centre, axis=1).max() + np.linalg.norm(cfg.gripper.hand_extent())
        near = np.flatnonzero(np.linalg.norm(cloud.points - centre, axis=1) <= reach)
        pts = cloud.points[near]
        normals = estimate_normals(pts, cfg.normal_radius)
        seg_nrm = normals[np.searchsorted(near, segment)]
        out = []
        for a in rng.choice(len(seg_pts), size=min(cfg.anchors, len(seg_pts)), replace=False):
            p, n = seg_pts[a], seg_nrm[a]
            if np.linalg.norm(n) < 0.5:
                continue
            to_robot = np.asarray(cfg.reach_center) - p
            n = n if n @ to_robot >= 0 else -n  # outward normal: the side the robot sees
            axis = self._long_axis(seg_pts, p, n)
            for tilt in cfg.approach_tilts_deg:
                approach = Rotation.from_rotvec(np.deg2rad(tilt) * axis).apply(-n)
                candidate = self._evaluate(pts, normals, seg_pts, p, approach, np.cross(axis, approach), segment_id)
                if candidate is not None:
                    out.append(candidate)
        return out

    def _long_axis(self, seg_pts: np.ndarray, p: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Direction of largest spread of the part near p, orthogonal to the normal."""
        near = seg_pts[np.linalg.norm(seg_pts - p, axis=1) < self.config.neighbourhood]
        if len(near) < 3:
            near = seg_pts
        proj = (near - near.mean(0)) - np.outer((near - near.mean(0)) @ n, n)
        _, _, vt = np.linalg.svd(proj, full_matrices=False)
        axis = vt[0] - n * (vt[0] @ n)
        if np.linalg.norm(axis) < 1e-6:  # isotropic (a knob): any tangent direction
            axis = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        return axis / np.linalg.norm(axis)

    def _evaluate(self, pts: np.ndarray, normals: np.ndarray, seg_pts: np.ndarray, anchor: np.ndarray, approach: np.ndarray,
                  closing: np.ndarray, segment_id: int) -> GraspCandidate | None:
        cfg, g = self.config, self.config.gripper
        T = tcp_pose(anchor + cfg.depth * approach, approach, closing)
        region = g.closing_region()
        local = points_in_tcp(seg_pts, T)
        inside = np.all((local >= region[0]) & (local <= region[1]), axis=1)
        if inside.sum() < cfg.min_points_between:
            return None
        y = local[inside, 1]
        T[:3, 3] += T[:3, 1] * (y.max() + y.min()) / 2.0  # centre the hand on the part
        width = float(y.max() - y.min())
        if width > g.max_opening - 0.01 or collides(g, pts, T, cfg.collision_tolerance):
            return None
        quality = self._antipodal_quality(pts, normals, T)
        if quality < cfg.min_quality:
            return None
        toward = anchor - np.asarray(cfg.reach_center)
        alignment = max(0.0, float(approach @ toward / np.linalg.norm(toward)))
        return GraspCandidate(T, width, quality * (0.5 + 0.5 * alignment), segment_id)

    def _antipodal_quality(self, pts: np.ndarray, normals: np.ndarray, T: np.ndarray) -> float:
        """Mean over both fingers of the best |cos| between a first-contact normal and the closing axis.

        The first contacts are the points within 5 mm of the extreme of the closing region on
        each side; a side without any is no grasp.
        """
        region = self.config.gripper.closing_region()
        local = points_in_tcp(pts, T)
        inside = np.all((local >= region[0]) & (local <= region[1]), axis=1)
        if inside.sum() < self.config.min_points_between:
            return 0.0
        y = local[inside, 1]
        cos = np.abs(normals[inside] @ T[:3, 1])
        good = np.cos(np.deg2rad(self.config.friction_deg))
        sides = []
        for side in (y >= y.max() - 0.005, y <= y.min() + 0.005):
            best = float(cos[side].max())
            sides.append(best if best >= good else best * 0.5)
        return float(np.mean(sides))
