"""Cheaper visual meshes for CPU rasterisation.

On lavapipe every camera transforms every visual vertex, so render time follows the triangle
count: the Panda's visual meshes alone are ~135k triangles, which makes a ring5 observation
cost 200-300 ms. Depth cameras at 320x240 cannot resolve that detail (a
pixel covers ~5 mm at 1 m), so untextured triangle-mesh parts above a budget are replaced by
quadric-decimated copies with the same material, pose and scale (Panda: 135k -> 22k
triangles, ring5 ~3x faster; the robot's depth is unchanged at the median, silhouettes move
by a pixel). Textured parts are kept: decimation would lose their UV mapping.
"""
from __future__ import annotations

import numpy as np
import open3d as o3d
import sapien

MAX_TRIANGLES_PER_PART = 600


def _decimated_part(
    part: sapien.render.RenderShapeTriangleMeshPart, max_triangles: int
) -> sapien.render.RenderShapeTriangleMesh | None:
    """A one-part mesh shape with at most ``max_triangles``, or None to keep the part as is."""
    triangles = np.asarray(part.triangles)
    material = part.material
    if len(triangles) <= max_triangles or material.base_color_texture is not None:
        return None
    mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(np.asarray(part.vertices, dtype=np.float64)),
        o3d.utility.Vector3iVector(triangles.astype(np.int32)),
    )
    mesh = mesh.simplify_quadric_decimation(max_triangles)
    mesh.compute_vertex_normals()
    vertices = np.asarray(mesh.vertices, dtype=np.float32)
    return sapien.render.RenderShapeTriangleMesh(
        vertices,
        np.asarray(mesh.triangles, dtype=np.uint32),
        np.asarray(mesh.vertex_normals, dtype=np.float32),
        np.zeros((len(vertices), 2), dtype=np.float32),
        material,
    )


def simplify_render_body(entity: sapien.Entity, max_triangles: int = MAX_TRIANGLES_PER_PART) -> bool:
    """Replace the entity's render body by one with decimated parts; False if nothing changed."""
    body = entity.find_component_by_type(sapien.render.RenderBodyComponent)
    if body is None:
        return False
    new_shapes, changed = [], False
    for shape in body.render_shapes:
        if not isinstance(shape, sapien.render.RenderShapeTriangleMesh):
            new_shapes.append(shape.clone())
            continue
        for part in shape.parts:
            simplified = _decimated_part(part, max_triangles)
            changed |= simplified is not None
            if simplified is None:
                simplified = sapien.render.RenderShapeTriangleMesh(
                    np.asarray(part.vertices, np.float32), np.asarray(part.triangles, np.uint32),
                    np.asarray(part.get_vertex_normal(), np.float32), np.asarray(part.get_vertex_uv(), np.float32), part.material,
                )
            simplified.set_local_pose(shape.local_pose)
            simplified.set_scale(shape.scale)
            simplified.set_front_face(shape.front_face)
            new_shapes.append(simplified)
    if not changed:
        return False
    replacement = sapien.render.RenderBodyComponent()
    for shape in new_shapes:
        replacement.attach(shape)
    replacement.visibility = body.visibility
    entity.remove_component(body)
    entity.add_component(replacement)
    return True
