"""Keypose execution (Pinocchio IK + Ruckig trajectories) and teleop of actaim2. Thin ROS adapters over the `actaim2` library."""
