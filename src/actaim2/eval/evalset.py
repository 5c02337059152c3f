"""The fixed evaluation set: which objects, and which seeds, every method is evaluated on.

Objects are a catalogue's splits (``actaim2.data.splits.CATALOGUES``). The generated one's, as in
the paper: seen objects (``train_seen``: the objects training used, instances 0-7 of the six
training categories), unseen instances (instances 8-15 of the same categories) and unseen
categories (window, box, safe). The partnet one's: real PartNet-Mobility folders in ``train``
(seen objects, new scenes), ``val``, ``test_unseen_instance`` and ``test_unseen_category`` (the
last two only under the protocol lock, ``protocol.py``). ``--objects DIR`` adds
PartNet-Mobility folders as one more split.

Seeds. Sample ``slot`` of an object resets the scene with ``reset_seed(object, slot)``, which
draws the placement jitter (and camera noise), and draws its mode / action with
``sample_seed(object, slot)``. Every method uses the same slots of an object, so rows are
compared on the same scenes. Reset seeds are disjoint from data collection's *by
construction*: collection resets with ``rng.integers(2**31)`` (``actaim2.data.collect``), so
every collected scene has a seed below 2**31; evaluation seeds are 2**31 + (a 31-bit number
derived from the object and the slot), always at or above it (the ``uint32`` seed of
``/reset_scene`` holds them). The seen split therefore shows training objects in placements
training never saw; the other splits show objects training never saw.

``EVAL_SET_VERSION`` is part of every derivation: changing it makes a new evaluation set, whose
results must not be mixed with an old one's (the results file records it).
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from actaim2.data.splits import (
    PARTNET,
    PARTNET_EXTRA,
    PARTNET_TEST_CATEGORY,
    PARTNET_TEST_INSTANCE,
    PARTNET_TRAIN,
    PARTNET_VAL,
    TRAIN,
    UNSEEN_CATEGORY,
    UNSEEN_INSTANCE,
)

EVAL_SET_VERSION = 1
EVAL_SEED_BASE = 2**31  # collection's reset seeds are all below this
FOLDERS = "folders"
SPLITS = (TRAIN, UNSEEN_INSTANCE, UNSEEN_CATEGORY)
SPLIT_TITLES = {TRAIN: "Seen objects", UNSEEN_INSTANCE: "Unseen instances", UNSEEN_CATEGORY: "Unseen categories",
                FOLDERS: "PartNet-Mobility folders", PARTNET_TRAIN: "Real, seen objects (train)",
                PARTNET_VAL: "Real, validation (val)",
                PARTNET_TEST_INSTANCE: "Real, unseen instances (test)",
                PARTNET_TEST_CATEGORY: "Real, unseen categories (test)",
                PARTNET_EXTRA: "Real, other categories (extra)"}
TABLE_SPLITS = (*SPLITS, *PARTNET.splits, FOLDERS)  # the order tables show splits in
_RESET, _SAMPLE, _PSEUDO = 1, 2, 3


@dataclass(frozen=True)
class EvalObject:
    split: str
    category: str
    instance: int  # -1 for a folder
    folder: str = ""  # a PartNet-Mobility folder ("" for a catalogue object)

    @property
    def key(self) -> str:
        """Stable name in task keys and tables: the catalogue object id, or folder:<name>."""
        return f"folder:{self.object_id}" if self.folder else self.object_id

    @property
    def object_id(self) -> str:
        """The object's id in a collected dataset: the catalogue object id, or the folder name."""
        if self.folder:
            return Path(self.folder).name
        from actaim2.sim.objects.catalog import object_id

        return object_id(self.category, self.instance)


def _derive(key: str, purpose: int, slot: int) -> int:
    return int(np.random.SeedSequence([EVAL_SET_VERSION, purpose, zlib.crc32(key.encode()), slot]).generate_state(1)[0])


def reset_seed(obj: EvalObject, slot: int) -> int:
    """The scene seed of sample ``slot`` of ``obj``: in [2**31, 2**32), never a collection seed."""
    return EVAL_SEED_BASE + _derive(obj.key, _RESET, slot) % EVAL_SEED_BASE


def sample_seed(obj: EvalObject, slot: int) -> int:
    """The seed of the mode / action draw of sample ``slot``."""
    return _derive(obj.key, _SAMPLE, slot)


def pseudo_order_seed(key: str, repetition: int) -> int:
    """Seed of the order in which repetition ``repetition`` of object ``key`` visits the pseudo-clusters."""
    return _derive(key, _PSEUDO, repetition)


def catalogue_objects(splits: tuple[str, ...] = SPLITS, instances_per_category: int = 0,
                      categories: tuple[str, ...] = ()) -> list[EvalObject]:
    """The catalogue's objects of ``splits`` (the first N instances per category when N > 0)."""
    from actaim2.sim.objects.catalog import SPLITS as CATALOGUE

    out = []
    for split in splits:
        for category, instances in CATALOGUE[split].items():
            if categories and category not in categories:
                continue
            chosen = list(instances)[:instances_per_category] if instances_per_category > 0 else list(instances)
            out += [EvalObject(split, category, i) for i in chosen]
    return out


def folder_objects(root: str | Path) -> list[EvalObject]:
    """PartNet-Mobility folders (``mobility.urdf`` inside): ``root`` itself or its sub-folders, sorted.

    The category is the folder's ``meta.json`` ``model_cat`` (PartNet-Mobility's), else ``unknown``.
    """
    from actaim2.sim.objects.model import read_meta

    root = Path(root)
    folders = [root] if (root / "mobility.urdf").is_file() else sorted(p for p in root.iterdir() if (p / "mobility.urdf").is_file())
    if not folders:
        raise ValueError(f"{root} holds no PartNet-Mobility object folder (a folder with mobility.urdf)")
    return [EvalObject(FOLDERS, str(read_meta(p).get("model_cat", "unknown")), -1, str(p.resolve())) for p in folders]


def partnet_objects(root: str | Path, splits: tuple[str, ...], instances_per_category: int = 0,
                    categories: tuple[str, ...] = ()) -> list[EvalObject]:
    """The partnet catalogue's objects of ``splits`` at ``root``
    (``data.real_objects.catalogue_folders``)."""
    from actaim2.data.real_objects import catalogue_folders

    return [EvalObject(f.split, f.category, -1, str(Path(f.folder).resolve()))
            for f in catalogue_folders(Path(root), splits, categories, instances_per_category)]
