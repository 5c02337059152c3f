"""Prepare real object folders for simulation: decompose their collision meshes into the hull cache.

Run once per dataset (``actaim2 prepare-objects DIR``) or by the sim node at start-up, never
inside a scene reset: a cold decomposition takes seconds per mesh. Only what the loader will
ask the cache for is prepared: the collision meshes of folders not written by the generator
(those are built from convex pieces), larger than :data:`.hulls.MIN_DECOMPOSED_SIZE` at the
scale the loader will give them (:mod:`.sizing`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ObjectLoadError
from .hulls import HullCache, MeshReport, needs_hulls, prepare_meshes
from .mesh import read_mesh
from .partnet import URDF_NAME, read_object_folder
from .sizing import fit_object


@dataclass
class ObjectReport:
    """One folder's preparation: its meshes' reports and the hull count the loader will use."""

    folder: Path
    scale: float
    meshes: int  # collision mesh files
    small: int  # one hull each without an entry (below MIN_DECOMPOSED_SIZE)
    reports: list[MeshReport] = field(default_factory=list)

    @property
    def hulls(self) -> int:
        return self.small + sum(r.hulls for r in self.reports)

    @property
    def cpu_s(self) -> float:
        return sum(r.cpu_s for r in self.reports)

    def count(self, outcome: str) -> int:
        return sum(r.outcome == outcome for r in self.reports)


def find_object_folders(path: Path) -> list[Path]:
    """``path`` itself if it is an object folder (has mobility.urdf), else its object subfolders
    (sorted by name). Raises ObjectLoadError when there is none."""
    path = Path(path).expanduser()
    if (path / URDF_NAME).is_file():
        return [path]
    if not path.is_dir():
        raise ObjectLoadError(f"{path}: no such folder")
    found = sorted(p for p in path.iterdir() if (p / URDF_NAME).is_file())
    if not found:
        raise ObjectLoadError(f"{path}: neither an object folder nor a folder of object folders (no */{URDF_NAME})")
    return found


def prepare_objects(folders: list[Path], cache: HullCache, workers: int = 1) -> list[ObjectReport]:
    """Decompose the collision meshes of each folder that the loader will look up (module
    docstring), all folders' meshes in one pool of ``workers`` processes; one report per folder."""
    plans = []
    for folder in folders:
        info = read_object_folder(folder)
        scale = 1.0 if info.generated else fit_object(info).scale
        wanted: list[Path] = []
        small: set[Path] = set()
        for meshes in ([] if info.generated else info.collisions.values()):
            for m in meshes:
                if m.path is not None and m.path not in wanted and m.path not in small:
                    if needs_hulls(read_mesh(m.path), np.asarray(m.scale) * scale):
                        wanted.append(m.path)
                    else:
                        small.add(m.path)
        plans.append((info, scale, wanted, small))
    reports = prepare_meshes([p for _, _, wanted, _ in plans for p in wanted], cache, workers)
    by_mesh = {r.mesh: r for r in reports}
    return [ObjectReport(info.folder, scale, len(info.collision_mesh_files()), len(small), [by_mesh[p] for p in wanted])
            for info, scale, wanted, small in plans]
