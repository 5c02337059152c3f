"""Simulation (SAPIEN 3, PhysX on the CPU), ROS-free.

  env            SimEnv: the Python API (reset, step, joint targets, observe, object DoFs, success)
  scene          the SAPIEN world: physics (+ render) system, ground, lights, robot, object
  robot          the arm as PD-driven articulation, gravity compensation, friction-only gripper
  objects/       the articulated-object library (generated, PartNet-Mobility layout) and loader
  success        the paper's success criterion (some DoF moved > 30% of its range)
  joint_trajectory, gripper_action   ros2_control-like trajectory and gripper semantics
  cameras, observe, render_*, sensor_noise   camera rigs and the two render paths
  urdf           visual-free URDF copies for physics-only scenes

The scripted expert and the SimEnv executor use both sim and control: see :mod:`actaim2.rollout`.
"""
