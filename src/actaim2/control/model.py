"""Pinocchio model of one arm: the arm joints as angles, the gripper locked, the `tcp` frame.

Pinocchio stores a continuous (unbounded revolute) joint as (cos, sin), so for the Kinova
j2s6s200 nq = 9 while nv = 6. Everything outside this module (IK results, trajectories,
/joint_states, SAPIEN) speaks *angles*, one per arm joint in ``RobotSpec.arm_joints`` order;
:meth:`RobotModel.to_q` / :meth:`RobotModel.to_angles` are the only conversions.

The model is built from :func:`actaim2.robots.movable_gripper_urdf` (the same file the
simulator loads) and reduced to the arm: gripper joints are locked open, so collision
checks use the open fingers, the widest the hand gets while it moves.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from actaim2.robots import RobotSpec, movable_gripper_urdf

TCP_FRAME = "tcp"


class RobotModel:
    """Arm kinematics (FK, Jacobians, limits) of a :class:`RobotSpec` with the canonical tcp."""

    def __init__(self, spec: RobotSpec):
        self.spec = spec
        urdf = str(movable_gripper_urdf(spec))
        full = pin.buildModelFromUrdf(urdf)
        full_geom = pin.buildGeomFromUrdf(full, urdf, pin.GeometryType.COLLISION)
        missing = [j for j in (*spec.arm_joints, *spec.gripper_joints) if not full.existJointName(j)]
        if missing:
            raise ValueError(f"{spec.urdf_path}: joints {missing} not in the URDF")
        if not full.existFrame(spec.flange_frame):
            raise ValueError(f"{spec.urdf_path}: flange frame '{spec.flange_frame}' not in the URDF")
        q_ref = pin.neutral(full)
        lock = []
        for jid in range(1, full.njoints):
            name = full.names[jid]
            if name in spec.arm_joints:
                continue
            lock.append(jid)
            if name in spec.gripper_joints:
                q_ref[full.joints[jid].idx_q] = spec.gripper_open
        self.model, self.geometry = pin.buildReducedModel(full, full_geom, lock, q_ref)
        model = self.model
        order = [model.getJointId(j) for j in spec.arm_joints]
        if order != sorted(order):
            raise ValueError(f"arm_joints {spec.arm_joints} are not in the URDF's kinematic order")
        flange = model.getFrameId(spec.flange_frame)
        placement = model.frames[flange].placement * pin.SE3(spec.T_flange_tcp[:3, :3], spec.T_flange_tcp[:3, 3])
        self.tcp_frame = model.addFrame(
            pin.Frame(TCP_FRAME, model.frames[flange].parentJoint, flange, placement, pin.FrameType.OP_FRAME)
        )
        self.data = model.createData()
        self.n = model.nv
        # Continuous joints: 2 configuration entries (cos, sin) for one velocity entry.
        self.continuous = np.array([model.joints[j].nq == 2 for j in range(1, model.njoints)])
        self._idx_q = np.array([model.joints[j].idx_q for j in range(1, model.njoints)])
        lower = np.full(self.n, -np.inf)
        upper = np.full(self.n, np.inf)
        bounded = ~self.continuous
        lower[bounded] = model.lowerPositionLimit[self._idx_q[bounded]]
        upper[bounded] = model.upperPositionLimit[self._idx_q[bounded]]
        self.lower, self.upper = lower, upper

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.spec.arm_joints

    def to_q(self, angles: np.ndarray) -> np.ndarray:
        """Pinocchio configuration (nq) from joint angles (nv)."""
        angles = np.asarray(angles, dtype=float)
        q = np.empty(self.model.nq)
        c = self.continuous
        q[self._idx_q[~c]] = angles[~c]
        q[self._idx_q[c]] = np.cos(angles[c])
        q[self._idx_q[c] + 1] = np.sin(angles[c])
        return q

    def to_angles(self, q: np.ndarray, near: np.ndarray | None = None) -> np.ndarray:
        """Joint angles from a configuration; continuous joints unwrapped to the value closest
        to ``near`` (the current joints), so a trajectory never takes the long way round."""
        angles = np.asarray(q, dtype=float)[self._idx_q].copy()
        c = self.continuous
        if c.any():
            angles[c] = np.arctan2(q[self._idx_q[c] + 1], q[self._idx_q[c]])
            if near is not None:
                ref = np.asarray(near, dtype=float)[c]
                angles[c] = ref + wrap_angle(angles[c] - ref)
        return angles

    def within_limits(self, angles: np.ndarray, tol: float = 1e-9) -> bool:
        return bool(np.all(angles >= self.lower - tol) and np.all(angles <= self.upper + tol))

    def fk(self, angles: np.ndarray) -> np.ndarray:
        """4x4 pose of `tcp` in `world` (the URDF root)."""
        return self.fk_se3(self.to_q(angles)).homogeneous

    def fk_se3(self, q: np.ndarray) -> pin.SE3:
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, self.tcp_frame).copy()

    def random_angles(self, rng: np.random.Generator) -> np.ndarray:
        """Uniform in the joint limits; continuous joints uniform in [-pi, pi)."""
        lo = np.where(self.continuous, -np.pi, self.lower)
        hi = np.where(self.continuous, np.pi, self.upper)
        return rng.uniform(lo, hi)


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles mapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi
