"""Articulated objects: generated per category from a seed, written in PartNet-Mobility layout.

  catalog     categories, instances, splits; generates and caches object folders
  categories  one recipe per category (faucet, table, ... safe, three-drawer shelf)
  parts       building blocks (boards, drawers, hinged panels, handles)
  model       the object as data, URDF / folder writer, handle annotations
  loader      loads any such folder into a SAPIEN scene and places it before the robot
  surface     points on an object's collision surfaces (the expert's obstacle cloud)
"""
