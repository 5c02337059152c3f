"""The simulated arm: a fixed-base articulation driven by PD joint drives, with a parallel gripper.

* Position control. Every arm joint has a PD drive (PhysX articulation drive: implicit, so
  stiff gains stay stable at 240 Hz) whose target position and velocity the caller sets; a
  trajectory follower sets both each physics step (velocity feed-forward), as a real joint
  position controller with feed-forward does.
* Gravity compensation. The robot's links ignore gravity: the ideal compensation a real
  torque-controlled arm (Panda, Jaco2) runs underneath position control. Forces from contacts
  and from whatever the gripper holds still act.
* Gripper. The finger joints are driven to a target with a force limit -- the grip force,
  per command (GripperCommand ``max_effort``) or the robot's default (Panda: 70 N
  continuous), converted to a joint effort through the pads' lever (:mod:`actaim2.gripper`)
  -- and their speed is capped like a real gripper's. The drive is stiff enough that a
  finger blocked more than ``GRIP_SATURATION_GAP`` short of its target pushes with the full
  limit: fingers closed on a handle squeeze it with the grip force, as a force-controlled
  gripper does. A grasp is friction between finger pads and the handle, nothing else: no
  attachment constraint, no joint is ever created on grasp, so opening the fingers releases
  the part, and a part pulled harder than friction x grip force slips out. The fingers get
  a high-friction material.

The URDF comes from :func:`actaim2.robots.movable_gripper_urdf` (gripper joints movable,
absolute mesh paths) - the same file Pinocchio loads for control.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sapien

from actaim2.gripper import gripper_geometry
from actaim2.robots import RobotSpec, movable_gripper_urdf, urdf_joint_limits
from actaim2.sim.urdf import parse_urdf

FINGER_FRICTION = 1.2  # rubber-like finger pads
GRIP_SATURATION_GAP = 1e-3  # m of gap short of the target at which a finger pushes with its full force
GRIP_TIME_CONSTANT = 0.01  # s: gripper drive damping = stiffness x this (no overshoot at the target)


@dataclass(frozen=True)
class DriveGains:
    """PD gains of the joint drives (SI units: N m/rad or N/m, N m s/rad or N s/m)."""

    arm_stiffness: float = 10000.0
    arm_damping: float = 1000.0
    gripper_stiffness: float | None = None  # None: the default grip force over GRIP_SATURATION_GAP (joint units)
    gripper_damping: float | None = None  # None: stiffness x GRIP_TIME_CONSTANT
    gripper_speed: float | None = None  # per finger (m/s or rad/s); None = the URDF velocity limit


class SimRobot:
    """One arm + parallel gripper in a SAPIEN scene, its base at the ``world`` origin."""

    def __init__(self, scene: sapien.Scene, spec: RobotSpec, keep_visuals: bool = False, gains: DriveGains = DriveGains()):
        self.spec = spec
        self.scene = scene  # SAPIEN frees the articulation with its scene: keep it alive
        urdf = movable_gripper_urdf(spec)
        limits = urdf_joint_limits(urdf)
        loader = scene.create_urdf_loader()
        loader.fix_root_link = True
        builders, actor_builders, _ = parse_urdf(loader, urdf, spec.srdf_path, keep_visuals=keep_visuals)
        if len(builders) != 1 or actor_builders:
            raise ValueError(f"{spec.urdf_path}: expected a single articulation")
        for lb in builders[0].link_builders:
            # continuous joints: keep angles unwrapped so targets like 3.5 rad mean 3.5 rad
            if lb.joint_record.joint_type == "revolute":
                lb.joint_record.joint_type = "revolute_unwrapped"
        self.articulation = builders[0].build()
        self.articulation.name = spec.name
        self.articulation.set_root_pose(sapien.Pose())
        joints = {j.name: j for j in self.articulation.get_active_joints()}
        missing = [n for n in spec.arm_joints + spec.gripper_joints if n not in joints]
        if missing:
            raise ValueError(f"{spec.name}: joints {missing} are not movable joints of {urdf}")
        active = [j.name for j in self.articulation.get_active_joints()]
        self.arm_joints = [joints[n] for n in spec.arm_joints]
        self.gripper_joints = [joints[n] for n in spec.gripper_joints]
        self.arm_index = np.array([active.index(n) for n in spec.arm_joints])
        self.gripper_index = np.array([active.index(n) for n in spec.gripper_joints])
        for j in self.arm_joints:
            j.set_drive_property(gains.arm_stiffness, gains.arm_damping, force_limit=limits[j.name][0])
        self.gripper = gripper_geometry(spec)
        per_gap = abs(self.gripper.joint_from_gap(GRIP_SATURATION_GAP) - self.gripper.joint_from_gap(0.0))
        self._gripper_stiffness = gains.gripper_stiffness or self.gripper.effort_from_force(0.0) / per_gap
        self._gripper_damping = gains.gripper_damping or self._gripper_stiffness * GRIP_TIME_CONSTANT
        self.set_gripper_force(0.0)
        for j in self.gripper_joints:
            j.set_max_velocity(gains.gripper_speed if gains.gripper_speed is not None else limits[j.name][1])
        for link in self.articulation.links:
            link.disable_gravity = True
        finger_material = sapien.physx.PhysxMaterial(FINGER_FRICTION, FINGER_FRICTION, 0.0)
        for link in self.finger_links():
            for shape in link.collision_shapes:
                shape.set_physical_material(finger_material)
        flanges = [link for link in self.articulation.links if link.name == spec.flange_frame]
        if not flanges:
            raise ValueError(f"{spec.name}: flange frame '{spec.flange_frame}' is not a link of {urdf}")
        self.flange = flanges[0]
        self.reset(spec.home, spec.gripper_open)

    @property
    def links(self) -> list:
        return list(self.articulation.links)

    @property
    def joint_names(self) -> list[str]:
        """Arm joints then gripper joints: the order of :meth:`joint_positions` and /joint_states."""
        return list(self.spec.arm_joints + self.spec.gripper_joints)

    def finger_links(self) -> list:
        """Links moved by the gripper joints (the fingers and everything they carry)."""
        roots = {j.child_link.name for j in self.gripper_joints}
        out, stack = [], [link for link in self.articulation.links if link.name in roots]
        while stack:
            link = stack.pop()
            out.append(link)
            stack.extend(link.children)
        return out

    def reset(self, arm: np.ndarray, gripper: float) -> None:
        """Teleport to ``arm`` joint angles with every finger at ``gripper``, at rest, holding there."""
        arm = np.asarray(arm, dtype=float)
        if arm.shape != (len(self.arm_joints),):
            raise ValueError(f"{self.spec.name} has {len(self.arm_joints)} arm joints, got {arm.shape}")
        q = np.zeros(self.articulation.dof)
        q[self.arm_index] = arm
        q[self.gripper_index] = gripper
        self.articulation.set_qpos(q)
        self.articulation.set_qvel(np.zeros_like(q))
        self.set_arm_target(arm)
        self.set_gripper_target(gripper)

    def set_arm_target(self, q: np.ndarray, qd: np.ndarray | None = None) -> None:
        """PD targets of the arm joints (positions, and velocities as feed-forward)."""
        for i, joint in enumerate(self.arm_joints):
            joint.set_drive_target(float(q[i]))
            joint.set_drive_velocity_target(0.0 if qd is None else float(qd[i]))

    def set_gripper_target(self, position: float) -> None:
        """Drive every finger joint towards ``position`` (the spec's open / closed values or between)."""
        for joint in self.gripper_joints:
            joint.set_drive_target(float(position))

    def set_gripper_force(self, force: float) -> None:
        """Grip force limit in N (0 = the robot's default), as GripperCommand's ``max_effort``."""
        if not (np.isfinite(force) and force >= 0.0):
            raise ValueError(f"grip force must be a finite number >= 0 N, got {force}")
        self.grip_force = force if force > 0.0 else self.gripper.default_force
        effort = self.gripper.effort_from_force(self.grip_force)
        for j in self.gripper_joints:
            j.set_drive_property(self._gripper_stiffness, self._gripper_damping, force_limit=effort)

    def gripper_gap(self) -> float:
        """Gap width (m) between the finger pads."""
        return self.gripper.gap_from_joint(self.gripper_position())

    def gripper_target(self) -> float:
        return float(self.gripper_joints[0].drive_target[0])

    def joint_positions(self) -> np.ndarray:
        """Positions in :attr:`joint_names` order."""
        q = self.articulation.get_qpos()
        return np.concatenate([q[self.arm_index], q[self.gripper_index]]).astype(float)

    def joint_velocities(self) -> np.ndarray:
        qd = self.articulation.get_qvel()
        return np.concatenate([qd[self.arm_index], qd[self.gripper_index]]).astype(float)

    def arm_positions(self) -> np.ndarray:
        return np.asarray(self.articulation.get_qpos()[self.arm_index], dtype=float)

    def gripper_position(self) -> float:
        """Mean finger joint position."""
        return float(np.mean(self.articulation.get_qpos()[self.gripper_index]))

    def tcp_pose(self) -> np.ndarray:
        """4x4 pose of the canonical ``tcp`` in ``world``: flange link pose times T_flange_tcp."""
        return self.flange.entity_pose.to_transformation_matrix() @ self.spec.T_flange_tcp
