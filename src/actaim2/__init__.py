"""ActAIM2 core library (ROS-free).

Sub-packages, one job each:
  geometry      poses, quaternions (xyzw at ROS boundaries, wxyz for SAPIEN/Pinocchio)
  robots        robot presets (URDF, joints, canonical `tcp` frame, limits)
  sim           SAPIEN scene, articulated-object library, cameras, scripted expert
  perception    cloud codecs, static-transform buffer, fusion, self-filter, orthographic views
  control       Pinocchio IK, collision checks, Ruckig trajectories, four-phase primitive
  data          samplers, task embeddings, on-disk dataset, collection CLI
  bench         benchmark commands (`actaim2 bench ...`)
"""

__version__ = "0.1.0"
