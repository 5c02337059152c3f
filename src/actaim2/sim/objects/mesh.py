"""Triangle meshes as numpy arrays: OBJ files in and out, and how convex a mesh is.

PartNet-Mobility meshes (``textured_objs/*.obj``) are triangle soups: rarely closed, often
single-sided sheets, with vertices repeated per texture seam. So "how convex" is measured on
voxels, which need no closed surface: the mesh's solid is its surface voxels plus every
voxel the surface encloses, the hull's solid every voxel of its convex hull (both on one
grid, the hull dilated by half a voxel as the surface voxels are). A solid within 5% of its
hull's volume is one convex piece for physics; anything else (a bar on standoffs, a U-handle,
an open drawer box, a panel and its frame) is decomposed (:mod:`.hulls`).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

VOXELS = 40  # grid cells along the mesh's longest side for the convexity measure
SAMPLE_BATCH = 1_000_000  # surface points voxelised at once


@dataclass(frozen=True)
class Mesh:
    """Vertices (n x 3, float) and triangles (m x 3, int indices into the vertices)."""

    vertices: np.ndarray
    faces: np.ndarray

    @property
    def extent(self) -> np.ndarray:
        return np.ptp(self.vertices, axis=0) if len(self.vertices) else np.zeros(3)


def read_obj(path: Path) -> Mesh:
    """The vertices and triangles of a Wavefront OBJ file (polygons fanned into triangles;
    texture coordinates, normals, groups and materials ignored). A malformed line raises
    ValueError naming the file and line."""
    vertices: list[list[float]] = []
    faces: list[list[int]] = []
    with open(path, errors="replace") as f:
        for number, line in enumerate(f, 1):
            if line.startswith("v "):
                try:
                    vertices.append([float(x) for x in line.split()[1:4]])
                except ValueError:
                    raise ValueError(f"{path}: line {number}: bad vertex {line.strip()!r}") from None
                if len(vertices[-1]) != 3:
                    raise ValueError(f"{path}: line {number}: a vertex needs 3 coordinates, got {line.strip()!r}")
            elif line.startswith("f "):
                try:
                    index = [int(token.split("/")[0]) for token in line.split()[1:]]
                except ValueError:
                    raise ValueError(f"{path}: line {number}: bad face {line.strip()!r}") from None
                index = [i - 1 if i > 0 else len(vertices) + i for i in index]  # OBJ: 1-based, negative = relative
                if len(index) < 3 or min(index) < 0 or max(index) >= len(vertices):
                    raise ValueError(f"{path}: line {number}: face {line.strip()!r} names a vertex that does not exist")
                faces += [[index[0], index[k], index[k + 1]] for k in range(1, len(index) - 1)]
    return Mesh(np.asarray(vertices, dtype=float).reshape(-1, 3), np.asarray(faces, dtype=np.int64).reshape(-1, 3))


def read_mesh(path: Path) -> Mesh:
    """A mesh file's triangles: OBJ read here, other formats (STL, PLY, ...) through Open3D.
    Raises ValueError naming the file when it cannot be read."""
    path = Path(path)
    if path.suffix.lower() == ".obj":
        return read_obj(path)
    import open3d as o3d

    o3d_mesh = o3d.io.read_triangle_mesh(str(path))
    if len(o3d_mesh.triangles) == 0:
        raise ValueError(f"{path}: no triangles could be read from this mesh file")
    return Mesh(np.asarray(o3d_mesh.vertices, dtype=float), np.asarray(o3d_mesh.triangles, dtype=np.int64))


def write_obj(path: Path, parts: list[Mesh]) -> None:
    """Write ``parts`` as one OBJ file, one ``o`` object per part (SAPIEN's
    ``PhysxCollisionShapeConvexMesh.load_multiple`` makes one convex shape of each)."""
    lines, offset = [], 1
    for k, part in enumerate(parts):
        lines.append(f"o part_{k}\n")
        lines += [f"v {x:.7g} {y:.7g} {z:.7g}\n" for x, y, z in part.vertices]
        lines += [f"f {a + offset} {b + offset} {c + offset}\n" for a, b, c in part.faces]
        offset += len(part.vertices)
    Path(path).write_text("".join(lines))


def convex_hull(mesh: Mesh) -> Mesh:
    """The mesh's convex hull (joggled, so flat and degenerate meshes get one too)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(mesh.vertices, qhull_options="QJ")
    used, faces = np.unique(hull.simplices, return_inverse=True)
    return Mesh(mesh.vertices[used], faces.reshape(-1, 3))


def solid_fraction(mesh: Mesh, voxels: int = VOXELS) -> float:
    """Volume of the mesh's solid over its convex hull's, on one voxel grid (module docstring).

    1.0 for a box or any convex piece (up to a voxel's rounding); a bar handle on two
    standoffs or an open box comes out far lower."""
    from scipy import ndimage
    from scipy.spatial import ConvexHull, QhullError

    if len(mesh.faces) == 0:
        return 1.0
    lo = mesh.vertices.min(axis=0)
    size = max(float(mesh.extent.max()), 1e-9) / voxels
    shape = np.maximum(np.ceil(mesh.extent / size).astype(int), 1) + 3  # a free layer all around
    origin = lo - 1.5 * size
    surface = _surface_voxels(mesh, origin, size, shape)
    solid = ndimage.binary_fill_holes(surface)
    try:
        equations = ConvexHull(mesh.vertices, qhull_options="QJ").equations
    except QhullError:  # fewer than 4 distinct points: a segment or a point, convex
        return 1.0
    centres = origin + (np.indices(shape).reshape(3, -1).T + 0.5) * size
    inside = np.all(centres @ equations[:, :3].T + equations[:, 3] <= 0.5 * size, axis=1).reshape(shape)
    return float(solid.sum()) / float((inside | surface).sum())


def _surface_voxels(mesh: Mesh, origin: np.ndarray, size: float, shape: np.ndarray) -> np.ndarray:
    """Boolean grid of the voxels every triangle passes through (points spaced under half a voxel)."""
    grid = np.zeros(shape, dtype=bool)
    a, b, c = (mesh.vertices[mesh.faces[:, k]] for k in range(3))
    longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1)], axis=0)
    steps = np.maximum(np.ceil(2.0 * longest / size).astype(int), 1)
    for n in np.unique(steps):
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        u, v = i[keep] / n, j[keep] / n  # barycentric grid over the triangle
        rows = np.flatnonzero(steps == n)
        batch = max(1, SAMPLE_BATCH // len(u))  # bounded memory
        for start in range(0, len(rows), batch):
            r = rows[start:start + batch]
            points = a[r, None] + u[:, None] * (b - a)[r, None] + v[:, None] * (c - a)[r, None]
            cells = np.clip(np.floor((points.reshape(-1, 3) - origin) / size).astype(int), 0, shape - 1)
            grid[cells[:, 0], cells[:, 1], cells[:, 2]] = True
    return grid


def decimate(mesh: Mesh, max_faces: int) -> Mesh:
    """The mesh simplified (quadric decimation, Open3D) to at most ``max_faces`` triangles; a
    mesh already that small is returned as it is."""
    if len(mesh.faces) <= max_faces:
        return mesh
    import open3d as o3d

    o3d_mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.vertices), o3d.utility.Vector3iVector(mesh.faces))
    o3d_mesh.merge_close_vertices(1e-6 * float(mesh.extent.max()))
    simple = o3d_mesh.simplify_quadric_decimation(max_faces)
    return Mesh(np.asarray(simple.vertices, dtype=float), np.asarray(simple.triangles, dtype=np.int64))
