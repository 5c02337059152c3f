"""Articulated objects: generated per category from a seed, written in PartNet-Mobility layout.

  catalog     categories, instances, splits; generates and caches object folders
  categories  one recipe per category (faucet, table, ... safe, three-drawer shelf)
  parts       building blocks (boards, drawers, hinged panels, handles)
  model       the object as data, URDF / folder writer, handle annotations
  loader      loads any such folder into a SAPIEN scene and places it before the robot
  partnet     reads and checks a real PartNet-Mobility folder (errors: ObjectLoadError)
  sizing      scale and front distance of a real object (category size, workspace cube)
  hulls, mesh convex decomposition (CoACD) of collision meshes, cached; OBJ and convexity
  prepare     `actaim2 prepare-objects`: fills the hull cache before any scene is built
  surface     points on an object's collision surfaces (the expert's obstacle cloud)
"""
