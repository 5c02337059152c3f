"""The object library: categories, instances and the evaluation splits, in one place.

Categories follow the paper: six training categories (seen instances 0-7, unseen instances
8-15) and three held-out categories (instances 0-7), plus the real robot's three-drawer shelf.
Instances 16-23 of the training categories (``train_extra``) are more training objects that no
evaluation uses: drawn after the unseen instances, so the near-duplicate rule keeps them apart
from those too, and adding them changed no earlier instance.
An instance is generated from a seed derived from (category, instance), so every process
builds the same object; the generated folder is cached on disk in PartNet-Mobility layout.

Instance ``i`` has structure ``LAYOUTS[category][i mod n]`` (at least four per category).
No two instances are near-duplicates: two instances of a category are near-duplicates when
they have the same structure signature (layout, and each movable part's joint type, part
kind and handle kind, in order) and their sizes differ by less than
``NEAR_DUPLICATE_DISTANCE`` (root mean square over the recipe's sizes, each normalised to the
range it is drawn from, so 0.15 is 15 % of the ranges on average). An instance that would be a
near-duplicate of an earlier one is redrawn from the next seed of its own sequence
(``instance_seed`` and then crc32 of ``<object_id>#<k>``), so the catalogue stays
deterministic.
"""
from __future__ import annotations

import copy
import os
import shutil
import tempfile
import zlib
from pathlib import Path

import numpy as np

from .categories import LAYOUTS, RECIPES
from .model import FORMAT_VERSION, ObjectModel, read_meta

NEAR_DUPLICATE_DISTANCE = 0.15
MAX_REDRAWS = 50

TRAIN_CATEGORIES = ("faucet", "table", "storage_furniture", "door", "refrigerator", "switch")
HELDOUT_CATEGORIES = ("window", "box", "safe")
REAL_ROBOT_OBJECTS = ("three_drawer_shelf",)
INSTANCES_PER_SPLIT = 8

SPLITS: dict[str, dict[str, range]] = {
    "train_seen": {c: range(0, INSTANCES_PER_SPLIT) for c in TRAIN_CATEGORIES},
    "train_unseen_instance": {c: range(INSTANCES_PER_SPLIT, 2 * INSTANCES_PER_SPLIT) for c in TRAIN_CATEGORIES},
    "train_extra": {c: range(2 * INSTANCES_PER_SPLIT, 3 * INSTANCES_PER_SPLIT) for c in TRAIN_CATEGORIES},
    "heldout_category": {c: range(0, INSTANCES_PER_SPLIT) for c in HELDOUT_CATEGORIES},
    "real_robot": {c: range(0, 1) for c in REAL_ROBOT_OBJECTS},
}


def list_categories() -> list[str]:
    """Every category the generator knows, training ones first."""
    return list(TRAIN_CATEGORIES + HELDOUT_CATEGORIES + REAL_ROBOT_OBJECTS)


def split_instances(split: str) -> list[tuple[str, int]]:
    """(category, instance) pairs of a split, e.g. ``split_instances("train_seen")``."""
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r}; splits are {list(SPLITS)}")
    return [(c, i) for c, r in SPLITS[split].items() for i in r]


def category_instances(category: str) -> list[int]:
    """All catalogued instances of a category (over every split)."""
    _check_category(category)
    return sorted({i for split in SPLITS.values() for i in split.get(category, ())})


def object_id(category: str, instance: int) -> str:
    return f"{category}_{int(instance):03d}"


def instance_seed(category: str, instance: int) -> int:
    """A stable seed per (category, instance): the same object in every process and run."""
    return zlib.crc32(object_id(category, instance).encode())


def structure_signature(model: ObjectModel) -> tuple:
    """What makes two instances the same structure: the layout and, per movable part in order,
    its joint type, part kind and handle kind."""
    handle_kind = {h.joint: h.kind for h in model.handles}
    parts = tuple((j.type, j.semantic, handle_kind.get(j.name, "")) for j in model.movable_joints())
    return (model.params.get("layout", ""), parts)


def size_distance(a: ObjectModel, b: ObjectModel) -> float:
    """Root mean square difference of two instances' normalised sizes (``params["dims"]``)."""
    da, db = a.params.get("dims", {}), b.params.get("dims", {})
    keys = sorted(set(da) & set(db))
    if not keys:
        return 0.0
    return float(np.sqrt(np.mean([(da[k] - db[k]) ** 2 for k in keys])))


def near_duplicates(a: ObjectModel, b: ObjectModel) -> bool:
    """The catalogue's rule (module docstring): same structure signature and sizes closer than
    ``NEAR_DUPLICATE_DISTANCE``."""
    return structure_signature(a) == structure_signature(b) and size_distance(a, b) < NEAR_DUPLICATE_DISTANCE


_MODELS: dict[tuple[str, int], ObjectModel] = {}


def generate(category: str, instance: int) -> ObjectModel:
    """The object model of one instance (not written to disk)."""
    _check_category(category)
    if instance < 0:
        raise ValueError(f"instance must be >= 0, got {instance}")
    for i in range(instance + 1):  # every earlier instance first: the near-duplicate rule looks back
        if (category, i) not in _MODELS:
            _MODELS[(category, i)] = _draw(category, i)
    return copy.deepcopy(_MODELS[(category, instance)])


def _draw(category: str, instance: int) -> ObjectModel:
    layouts = LAYOUTS[category]
    layout = layouts[instance % len(layouts)]
    earlier = [_MODELS[(category, i)] for i in range(instance % len(layouts), instance, len(layouts))]
    oid = object_id(category, instance)
    for attempt in range(MAX_REDRAWS):
        seed = instance_seed(category, instance) if attempt == 0 else zlib.crc32(f"{oid}#{attempt}".encode())
        model = RECIPES[category](np.random.default_rng(seed), oid, layout)
        if not any(near_duplicates(model, other) for other in earlier):
            model.params.update(instance=int(instance), seed=int(seed))
            return model
    raise RuntimeError(f"{oid}: no draw in {MAX_REDRAWS} seeds differs from the earlier {layout} instances")


def default_cache_dir() -> Path:
    return Path(os.environ.get("ACTAIM2_CACHE", Path.home() / ".cache" / "actaim2")) / "objects"


def _is_current(folder: Path) -> bool:
    """Whether ``folder`` holds a complete object of this format (an older format is regenerated)."""
    return (folder / "mobility.urdf").is_file() and read_meta(folder).get("format_version") == FORMAT_VERSION


def object_folder(category: str, instance: int, cache_dir: Path | None = None) -> Path:
    """The PartNet-Mobility style folder of an instance, generated on first use.

    Written to a temporary folder and renamed into place, so concurrent processes (a sim
    node and a test, two collection workers) never see a half-written object. Only a folder
    of an older format is removed: one another process renamed into place while this one was
    generating is kept, because that process may be loading it already (removing it made
    collection workers fail with FileNotFoundError on an object's first trajectories).
    """
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    folder = cache / object_id(category, instance)
    if _is_current(folder):
        return folder
    model = generate(category, instance)
    cache.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}-", dir=cache))
    model.write_folder(tmp)
    if folder.exists() and not _is_current(folder):  # an older format
        shutil.rmtree(folder, ignore_errors=True)
    try:
        tmp.rename(folder)
    except OSError:  # another process won the race: its folder is equally good
        shutil.rmtree(tmp, ignore_errors=True)
    return folder


def _check_category(category: str) -> None:
    if category not in RECIPES:
        raise ValueError(f"unknown object category {category!r}; categories are {list_categories()}")
