"""Stored datasets in other projects' formats.

  lerobot_v21   a LeRobot dataset (format v2.1) of the keyframes, and its reader
  lerobot_v3    the same as LeRobot format v3.0 (episodes in shared files), and its reader
  lerobot_cli   `actaim2 export-lerobot` (from a dataset, or from teleop bags)
"""
