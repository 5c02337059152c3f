"""Executor driving :class:`actaim2.sim.env.SimEnv` directly (data collection, no ROS)."""
from __future__ import annotations

from typing import TYPE_CHECKING, Callable

import numpy as np

from actaim2.control.executor import StepResult
from actaim2.control.trajectory import JointTrajectory, State

if TYPE_CHECKING:
    from actaim2.sim.env import SimEnv


class SimEnvExecutor:
    """Steps the simulation through each trajectory (JTC interpolation) and gripper command."""

    def __init__(self, env: "SimEnv", settle: float = 0.1, gripper_timeout: float = 1.5):
        self.env = env
        self.settle = settle
        self.gripper_timeout = gripper_timeout
        self._arm = len(env.spec.arm_joints)

    def arm_state(self) -> State:
        _, position, velocity = self.env.joint_state()
        position = np.asarray(position[: self._arm], dtype=float)
        return State(position, np.asarray(velocity[: self._arm], dtype=float), np.zeros_like(position))

    def follow(self, trajectory: JointTrajectory, on_progress: Callable[[float], None]) -> StepResult:
        self.env.follow_trajectory(trajectory.times, trajectory.positions, trajectory.velocities, settle=self.settle)
        on_progress(1.0)
        return StepResult(True, "trajectory executed")

    def set_gripper(self, closed: bool) -> StepResult:
        # The fingers stop on a handle or at their target: both are success (GripperCommand's "stalled").
        position = self.env.grip(closed, timeout=self.gripper_timeout)
        return StepResult(True, f"gripper {'closed' if closed else 'open'} at {position:.4f}")
