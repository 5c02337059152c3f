"""Stored datasets in other projects' formats.

  lerobot_v21   a LeRobot dataset (format v2.1) of the keyframes, and its reader
  lerobot_cli   `actaim2 export-lerobot`
"""
