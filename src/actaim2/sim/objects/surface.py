"""Points on an articulated object's collision surfaces, in ``world``.

Privileged geometry for the scripted expert's collision checks (the object as an obstacle
cloud for the arm's free moves); policies only ever see camera clouds.
"""
from __future__ import annotations

import numpy as np
import open3d as o3d

from actaim2.sim.render_raycast import collision_shape_mesh


def surface_points(links: list, spacing: float = 0.01) -> np.ndarray:
    """(N, 3) points spread over the collision shapes of ``links`` at their current poses,
    about ``spacing`` apart (area-weighted uniform sampling)."""
    out = [np.zeros((0, 3))]
    for link in links:
        T_link = link.entity_pose.to_transformation_matrix()
        for shape in link.collision_shapes:
            local = collision_shape_mesh(shape)
            if local is None:
                continue
            mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(local[0]), o3d.utility.Vector3iVector(local[1]))
            n = max(8, int(mesh.get_surface_area() / spacing**2))
            T = T_link @ shape.local_pose.to_transformation_matrix()
            points = np.asarray(mesh.sample_points_uniformly(n).points)
            out.append(points @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(out)
