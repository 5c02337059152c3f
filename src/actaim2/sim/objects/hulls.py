"""Collision hulls that keep concave parts graspable: CoACD decomposition, cached outside the dataset.

PhysX simulates convex shapes. One hull per mesh file (what SAPIEN does with a URDF mesh)
turns a bar handle on two standoffs into a solid block the fingers cannot wrap, an open
drawer into a filled box. So each collision mesh is decomposed once, before any scene is
built (``actaim2 prepare-objects`` or the sim node's start-up, never inside ``/reset_scene``),
and the loader reads the hulls from the cache:

* the cache is a user-chosen folder (default ``$ACTAIM2_CACHE/hulls``, else
  ``~/.cache/actaim2/hulls``), never the dataset folder; an entry is one OBJ file with one
  ``o`` object per hull, named by the SHA-256 of the mesh file's bytes and a digest of the
  decomposition parameters (:meth:`HullParams.key`), so an edited mesh or new parameters get
  new entries and identical meshes share one;
* a mesh whose solid lies within 5% of its convex hull's volume
  (:func:`.mesh.solid_fraction` >= ``convex_fraction``) is not decomposed: its entry is that
  one hull;
* a mesh smaller than :data:`MIN_DECOMPOSED_SIZE` at the object's scale is one hull without
  an entry: no fingertip fits into its concavities;
* a mesh with no entry when an object loads is one hull, and the loader logs a warning that
  says to run ``actaim2 prepare-objects``.

CoACD at its defaults took 17-897 s per shared PartNet-Mobility object on 2 cores. The
defaults of :class:`HullParams` trade detail for time (figures in README "Simulation"):
concavity threshold 0.1 (CoACD normalises a mesh to its bounding box: the gap behind a bar
handle stays open), a manifold pre-pass at resolution 40 (at 20 it thickened a 2-cm bar by
1.4 cm, closing most of the gap a fingertip needs; at 40 by 2 mm), a shallower tree search
(50 iterations, depth 2, 10 nodes), no cap on the hull count (capping made CoACD's merge pass
the slowest part), hulls simplified to at most 32 vertices (cheaper contacts), and input
meshes above 2000 triangles decimated first. Meshes below MIN_DECOMPOSED_SIZE and near-convex
ones skip CoACD, which is most of the saving on PartNet-Mobility objects.
"""
from __future__ import annotations

import hashlib
import json
import logging
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from actaim2.progress import progress

from .errors import ObjectLoadError
from .mesh import Mesh, convex_hull, decimate, read_mesh, solid_fraction, write_obj

CACHE_FORMAT = 1  # bump to invalidate every cache entry (the entry layout changed)
MIN_DECOMPOSED_SIZE = 0.04  # m: a mesh whose largest side is below this (at the object's scale) is one hull
LOG = logging.getLogger("actaim2.sim.hulls")


@dataclass(frozen=True)
class HullParams:
    """CoACD settings and the skip rule (see the module docstring for why these values)."""

    threshold: float = 0.1  # CoACD concavity threshold (of the mesh normalised to its bounding box)
    preprocess_resolution: int = 40  # CoACD manifold pre-pass voxel resolution
    resolution: int = 1000  # CoACD surface samples for the concavity measure
    mcts_nodes: int = 10
    mcts_iterations: int = 50
    mcts_max_depth: int = 2
    max_convex_hull: int = -1  # -1: no cap
    max_hull_vertices: int = 32  # each hull simplified to at most this many vertices
    max_input_faces: int = 2000  # larger meshes are decimated before decomposition
    convex_fraction: float = 0.95  # solid / hull volume at or above which a mesh is one hull
    seed: int = 0

    def key(self) -> str:
        """12 hex digits naming these settings (and the CoACD version and cache format)."""
        from importlib.metadata import version

        text = json.dumps({**asdict(self), "coacd": version("coacd"), "format": CACHE_FORMAT}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:12]


@dataclass(frozen=True)
class MeshReport:
    """What preparing one mesh did: ``outcome`` is decomposed, convex or cached."""

    mesh: Path
    outcome: str
    hulls: int
    cpu_s: float
    wall_s: float


def default_hull_dir() -> Path:
    return Path(os.environ.get("ACTAIM2_CACHE", Path.home() / ".cache" / "actaim2")) / "hulls"


def file_digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


class HullCache:
    """The hull entries of one cache folder under one set of parameters."""

    def __init__(self, root: Path | None = None, params: HullParams = HullParams()):
        self.root = Path(root).expanduser() if root is not None else default_hull_dir()
        self.params = params
        self._key = params.key()

    def entry(self, mesh: Path) -> Path:
        """Where the hulls of ``mesh`` are (or would be) stored."""
        digest = file_digest(mesh)
        return self.root / digest[:2] / f"{digest}-{self._key}.obj"

    def lookup(self, mesh: Path) -> Path | None:
        entry = self.entry(mesh)
        return entry if entry.is_file() else None

    def prepare(self, mesh: Path) -> MeshReport:
        """Decompose ``mesh`` into the cache unless its entry exists (module docstring)."""
        wall, cpu = time.perf_counter(), time.process_time()
        entry = self.entry(mesh)
        if entry.is_file():
            return MeshReport(Path(mesh), "cached", count_hulls(entry), 0.0, time.perf_counter() - wall)
        try:
            source = read_mesh(mesh)
        except (OSError, ValueError) as error:
            raise ObjectLoadError(f"{mesh}: cannot read the collision mesh ({error})") from None
        if len(source.faces) == 0 or solid_fraction(source) >= self.params.convex_fraction:
            parts, outcome = [convex_hull(source)] if len(source.vertices) >= 4 else [source], "convex"
        else:
            parts, outcome = decompose(source, self.params), "decomposed"
        entry.parent.mkdir(parents=True, exist_ok=True)
        tmp = entry.with_name(f".{entry.name}.{os.getpid()}.tmp")
        write_obj(tmp, parts)
        os.replace(tmp, entry)  # atomic: a concurrent reader sees no entry or a whole one
        return MeshReport(Path(mesh), outcome, len(parts), time.process_time() - cpu, time.perf_counter() - wall)


def decompose(mesh: Mesh, params: HullParams) -> list[Mesh]:
    """CoACD's convex parts of ``mesh`` (decimated first when it is large)."""
    import coacd

    coacd.set_log_level("error")
    mesh = decimate(mesh, params.max_input_faces)
    parts = coacd.run_coacd(
        coacd.Mesh(mesh.vertices, mesh.faces), threshold=params.threshold, max_convex_hull=params.max_convex_hull,
        preprocess_mode="auto", preprocess_resolution=params.preprocess_resolution, resolution=params.resolution,
        mcts_nodes=params.mcts_nodes, mcts_iterations=params.mcts_iterations, mcts_max_depth=params.mcts_max_depth,
        merge=True, decimate=True, max_ch_vertex=params.max_hull_vertices, seed=params.seed,
    )
    return [Mesh(np.asarray(v, dtype=float), np.asarray(f, dtype=np.int64)) for v, f in parts]


def count_hulls(entry: Path) -> int:
    with open(entry) as f:
        return sum(1 for line in f if line.startswith("o "))


def _prepare_one(job: tuple[Path, HullParams, Path]) -> MeshReport:
    mesh, params, root = job
    return HullCache(root, params).prepare(mesh)


def prepare_meshes(meshes: list[Path], cache: HullCache, workers: int = 1) -> list[MeshReport]:
    """Prepare every mesh (in ``workers`` processes when > 1); reports in the given order."""
    meshes = list(dict.fromkeys(Path(m) for m in meshes))
    bar = progress(total=len(meshes), desc="convex hulls", unit="mesh")
    if workers <= 1 or len(meshes) < 2:
        with bar:
            return [_counted(cache.prepare(m), bar) for m in meshes]
    import multiprocessing as mp

    # largest first, so no long mesh starts last and leaves the other worker idle
    order = sorted(range(len(meshes)), key=lambda k: -meshes[k].stat().st_size)
    spawn = mp.get_context("spawn")
    with bar, ProcessPoolExecutor(min(workers, len(meshes)), mp_context=spawn) as pool:
        jobs = [(meshes[k], cache.params, cache.root) for k in order]
        done = dict(zip(order, (_counted(r, bar) for r in pool.map(_prepare_one, jobs))))
    return [done[k] for k in range(len(meshes))]


def _counted(report: MeshReport, bar) -> MeshReport:
    bar.update(1)
    return report


def needs_hulls(mesh: Mesh, scale: np.ndarray) -> bool:
    """Whether a mesh at ``scale`` (per axis) is large enough to be decomposed (module docstring)."""
    return float(np.max(mesh.extent * np.abs(scale))) >= MIN_DECOMPOSED_SIZE
