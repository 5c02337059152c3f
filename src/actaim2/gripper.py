"""A parallel gripper's gap width, its finger joint positions, and grip force <-> joint effort.

``control_msgs/GripperCommand`` speaks of the gap between the fingers (m) and a force limit
(N); drivers command finger joints: Panda's fingers slide (each is half the gap), Jaco2's
fingers turn, and the gap between their distal pads is a curve in the angle. Both the
simulator's GripperCommand server and ``control_node`` convert through this one module, so a
goal means the same gap on every robot and on either side of the wire.

The curve is measured from the robot's own collision geometry (Pinocchio + coal): at each of
``SAMPLES`` finger positions from open to closed, the distance between the two fingers'
distal pads -- the collision geometry of the last link of each finger's chain, where a handle
is held. For revolute fingers the lever is the distance from the finger joint axis to the
nearest pad point, so a grip force F becomes a joint torque F x lever. Computed once per
robot URDF and cached next to the cached URDF (:func:`actaim2.robots.write_cached_urdf`).
Beyond the measured range the curve is extended linearly: a gap narrower than the closed one
commands the fingers past their closed position, where they stall, as real grippers do.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from actaim2.robots import RobotSpec, movable_gripper_urdf, urdf_joint_limits

SAMPLES = 33
POSITION_UNITS = ("gap_width", "finger_joint")  # what a driver's GripperCommand position means


@dataclass(frozen=True)
class GripperGeometry:
    """Gap width (m) and lever (m) sampled along the finger joint positions (open -> closed)."""

    joint: np.ndarray
    gap: np.ndarray
    lever: np.ndarray  # revolute fingers: joint axis -> pad contact; prismatic: 1 (force = effort)
    default_force: float  # N: the grip force when a command gives none (max_effort 0)

    def gap_from_joint(self, q: float) -> float:
        """Gap width (m) at finger joint position ``q``."""
        return float(_interp(q, self.joint, self.gap))

    def joint_from_gap(self, gap: float) -> float:
        """Finger joint position (joint units) that opens the fingers to ``gap`` metres."""
        return float(_interp(gap, self.gap, self.joint))

    def effort_from_force(self, force: float) -> float:
        """Per-finger joint effort (N or N m) that squeezes with ``force`` N (0 = the default)."""
        return (force if force > 0.0 else self.default_force) * float(np.median(self.lever))

    def force_from_effort(self, effort: float) -> float:
        return effort / float(np.median(self.lever))

    def to_unit(self, gap: float, unit: str) -> float:
        """A gap width expressed in a driver's position unit (:data:`POSITION_UNITS`)."""
        _check_unit(unit)
        return gap if unit == "gap_width" else self.joint_from_gap(gap)

    def from_unit(self, position: float, unit: str) -> float:
        """A driver's position (in ``unit``) as a gap width."""
        _check_unit(unit)
        return position if unit == "gap_width" else self.gap_from_joint(position)


def _check_unit(unit: str) -> None:
    if unit not in POSITION_UNITS:
        raise ValueError(f"gripper position unit must be one of {POSITION_UNITS}, got {unit!r}")


def _interp(x: float, xs: np.ndarray, ys: np.ndarray) -> float:
    """Piecewise-linear y(x) through samples with monotonic xs, extended linearly at both ends."""
    order = np.argsort(xs)
    xs, ys = xs[order], ys[order]
    if x < xs[0]:
        return ys[0] + (x - xs[0]) * (ys[1] - ys[0]) / (xs[1] - xs[0])
    if x > xs[-1]:
        return ys[-1] + (x - xs[-1]) * (ys[-1] - ys[-2]) / (xs[-1] - xs[-2])
    return float(np.interp(x, xs, ys))


def gripper_geometry(spec: RobotSpec) -> GripperGeometry:
    """The gripper curve of a robot (measured once per URDF content, then read from the cache)."""
    return _geometry(spec.name, str(movable_gripper_urdf(spec)), spec.gripper_joints, spec.gripper_open,
                     spec.gripper_closed, spec.gripper_force)


@lru_cache(maxsize=8)
def _geometry(name: str, urdf: str, joints: tuple[str, ...], q_open: float, q_closed: float,
              force: float | None) -> GripperGeometry:
    from pathlib import Path

    cache = Path(urdf).with_suffix(".gripper.json")
    if cache.is_file():
        data = json.loads(cache.read_text())
    else:
        data = _measure(urdf, joints, q_open, q_closed)
        tmp = cache.with_suffix(f".{np.random.default_rng().integers(1 << 30)}.tmp")
        tmp.write_text(json.dumps(data))
        tmp.replace(cache)
    lever = np.asarray(data["lever"], dtype=float)
    if force is None:  # the URDF's effort limit, as a force at the pads
        force = min(urdf_joint_limits(Path(urdf))[j][0] for j in joints) / float(np.median(lever))
    return GripperGeometry(np.asarray(data["joint"], float), np.asarray(data["gap"], float), lever, float(force))


def _measure(urdf: str, joints: tuple[str, ...], q_open: float, q_closed: float) -> dict:
    import coal
    import pinocchio as pin

    model = pin.buildModelFromUrdf(urdf)
    geom = pin.buildGeomFromUrdf(model, urdf, pin.GeometryType.COLLISION)
    data, gdata = model.createData(), geom.createData()
    ids = [model.getJointId(j) for j in joints]
    pads = []
    for jid in ids:
        chain = [i for i, g in enumerate(geom.geometryObjects) if jid in list(model.supports[g.parentJoint])]
        if not chain:
            raise ValueError(f"{urdf}: gripper joint {model.names[jid]} carries no collision geometry")
        # fixed joints (a distal phalanx on its proximal one) are merged into frames: depth is counted in frames
        depth = {i: _frame_depth(model, geom.geometryObjects[i].parentFrame) for i in chain}
        pads.append([i for i in chain if depth[i] == max(depth.values())])
    q = pin.neutral(model)
    out = {"joint": [], "gap": [], "lever": []}
    for value in np.linspace(q_open, q_closed, SAMPLES):
        for jid in ids:
            q[model.joints[jid].idx_q] = value
        pin.forwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, geom, gdata, q)
        best, point = np.inf, None
        for i in pads[0]:
            for j in pads[1]:
                result = coal.DistanceResult()
                d = coal.distance(geom.geometryObjects[i].geometry, gdata.oMg[i], geom.geometryObjects[j].geometry,
                                  gdata.oMg[j], coal.DistanceRequest(), result)
                if d < best:
                    best, point = d, np.asarray(result.getNearestPoint1())
        # the finger joint's motion in world: an angular axis (revolute) or none (prismatic)
        pin.computeJointJacobians(model, data, q)
        column = pin.getJointJacobian(model, data, ids[0], pin.ReferenceFrame.WORLD)[:, model.joints[ids[0]].idx_v]
        axis = column[3:]
        lever = 1.0
        if np.linalg.norm(axis) > 1e-9:
            axis = axis / np.linalg.norm(axis)
            r = point - data.oMi[ids[0]].translation
            lever = float(np.linalg.norm(r - (r @ axis) * axis))
        out["joint"].append(float(value))
        out["gap"].append(max(float(best), 0.0))
        out["lever"].append(lever)
    return out


def _frame_depth(model, frame: int) -> int:
    depth = 0
    while frame > 0:
        frame = model.frames[frame].parentFrame
        depth += 1
    return depth
