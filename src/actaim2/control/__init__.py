"""Arm control: Pinocchio model, IK, collision checks, Ruckig trajectories, keypose execution."""
