"""PartNet-Mobility folders as collection objects: their category and their split.

``actaim2 collect --objects DIR`` collects on every object folder in DIR (a folder of object
folders, or one). Objects are keyed by folder name; their category is meta.json's
``model_cat`` in the catalogue's spelling (:func:`actaim2.sim.objects.partnet.category_name`).

The ``partnet`` catalogue (``actaim2.data.splits.PARTNET``) is a folder of object folders with a
``splits.yaml`` beside them (``folder name: split``, the split names of that catalogue). Where
the folder is: ``--partnet-root``, else the environment variable ``ACTAIM2_PARTNET``; nothing by
default (users download PartNet-Mobility themselves). Under it every object's split is the one
its splits file names; a folder the file does not list is refused, never given a split.

Split of a folder collected without a catalogue (``--objects`` alone): the YAML given with
``--object-splits`` where it names the folder, else by category, as the generated catalogue
splits its own objects:

* a generated training category (``TRAIN_CATEGORIES``): ``train_seen`` or
  ``train_unseen_instance``, half and half, fixed per folder by the CRC-32 of its name (so a
  folder keeps its split whatever else is collected);
* any other category (the generated held-out ones, and categories it does not have, such as
  ``oven``): ``heldout_category``.
"""

from __future__ import annotations

import os
import zlib
from dataclasses import dataclass
from pathlib import Path

import yaml

from actaim2.data.splits import CATALOGUES, PARTNET, TRAIN, UNSEEN_CATEGORY, UNSEEN_INSTANCE
from actaim2.sim.objects.catalog import TRAIN_CATEGORIES

SPLIT_NAMES = tuple(name for c in CATALOGUES.values() for name in c.splits)
PARTNET_ROOT_ENV = "ACTAIM2_PARTNET"
SPLITS_FILE = "splits.yaml"


@dataclass(frozen=True)
class FolderObject:
    """One real object folder to collect on."""

    folder: str
    category: str
    split: str

    @property
    def object_id(self) -> str:
        return Path(self.folder).name


def split_by_category(category: str, name: str) -> str:
    """The split of folder ``name`` of ``category`` when no YAML names it (module docstring)."""
    if category not in TRAIN_CATEGORIES:
        return UNSEEN_CATEGORY
    return TRAIN if zlib.crc32(name.encode()) % 2 == 0 else UNSEEN_INSTANCE


def read_object_splits(path: Path) -> dict[str, str]:
    """``folder name -> split`` from a YAML mapping; raises ValueError naming a bad entry."""
    try:
        data = yaml.safe_load(Path(path).read_text()) or {}
    except (OSError, yaml.YAMLError) as error:
        raise ValueError(f"{path}: cannot read the object splits ({error})") from None
    if not isinstance(data, dict):
        raise ValueError(
            f"{path}: expected a mapping 'folder name: split', got {type(data).__name__}"
        )
    bad = {str(k): v for k, v in data.items() if v not in SPLIT_NAMES}
    if bad:
        raise ValueError(f"{path}: splits must be one of {SPLIT_NAMES}; got {bad}")
    return {str(k): str(v) for k, v in data.items()}


def partnet_root(given: Path | None = None) -> Path:
    """The partnet catalogue's folder: ``given``, else $ACTAIM2_PARTNET (module docstring).
    Raises ValueError when neither is set or the folder has no splits file."""
    text = str(given) if given is not None else os.environ.get(PARTNET_ROOT_ENV, "")
    if not text:
        raise ValueError(
            "the partnet catalogue needs its folder: pass --partnet-root DIR (or set "
            f"{PARTNET_ROOT_ENV}) "
            f"to a folder of PartNet-Mobility objects with a {SPLITS_FILE}"
        )
    root = Path(text).expanduser()
    if not (root / SPLITS_FILE).is_file():
        raise ValueError(
            f"{root}: no {SPLITS_FILE} (folder name: split) there, so no partnet catalogue"
        )
    return root


def partnet_splits(root: Path) -> dict[str, str]:
    """``folder name -> split`` of the partnet catalogue at ``root``; only that catalogue's
    split names."""
    splits = read_object_splits(root / SPLITS_FILE)
    bad = {k: v for k, v in splits.items() if v not in PARTNET.splits}
    if bad:
        raise ValueError(
            f"{root / SPLITS_FILE}: the partnet catalogue's splits are {PARTNET.splits}; got {bad}"
        )
    return splits


def folder_objects(
    path: Path, splits: dict[str, str] | None = None, listed_only: bool = False
) -> list[FolderObject]:
    """The object folders under ``path`` with their categories and splits (module docstring).
    ``listed_only`` (the partnet catalogue): a folder ``splits`` does not name is a ValueError.
    Raises ObjectLoadError (a ValueError) for a folder that cannot be read."""
    from actaim2.sim.objects.partnet import read_object_folder
    from actaim2.sim.objects.prepare import find_object_folders

    splits = splits or {}
    folders = find_object_folders(path)
    unlisted = [f.name for f in folders if f.name not in splits]
    if listed_only and unlisted:
        raise ValueError(
            f"{path}: folder(s) {unlisted} are in no split of the partnet catalogue's splits "
            "file: "
            f"add them to it (folder name: split) or leave them out; they are never split by hash"
        )
    out = []
    for folder in folders:
        info = read_object_folder(folder)
        split = splits.get(info.object_id) or split_by_category(info.category, info.object_id)
        out.append(FolderObject(str(info.folder), info.category, split))
    return out


def catalogue_folders(
    root: Path,
    split_names: tuple[str, ...],
    categories: tuple[str, ...] = (),
    per_category: int = 0,
) -> list[FolderObject]:
    """The partnet catalogue's objects of ``split_names`` at ``root``, by split then folder name;
    only ``categories`` when given, the first ``per_category`` of each category and split when
    > 0."""
    from actaim2.sim.objects.partnet import read_object_folder

    PARTNET.check_splits(split_names, "the partnet catalogue")
    splits = partnet_splits(root)
    out = []
    for split in split_names:
        names = sorted((n for n, s in splits.items() if s == split), key=lambda n: (len(n), n))
        missing = [n for n in names if not (root / n).is_dir()]
        if missing:
            raise ValueError(
                f"{root}: {SPLITS_FILE} lists folder(s) {missing} of split {split} that are not "
                "there"
            )
        taken: dict[str, int] = {}
        for name in names:
            info = read_object_folder(root / name)
            if categories and info.category not in categories:
                continue
            taken[info.category] = taken.get(info.category, 0) + 1
            if per_category <= 0 or taken[info.category] <= per_category:
                out.append(FolderObject(str(info.folder), info.category, split))
    return out


def check_training_objects(entries: list[dict], splits: dict[str, str]) -> None:
    """Raise ValueError if a trajectory of a training split is on a real object that ``splits``
    (a partnet catalogue's splits file) puts in a split the models must not learn from."""
    from actaim2.data.splits import TRAINING_SPLITS

    leaked = sorted(
        {
            (e["object_id"], e["split"], splits[e["object_id"]])
            for e in entries
            if e["split"] in TRAINING_SPLITS
            and e.get("instance", -1) < 0
            and splits.get(e["object_id"], e["split"]) not in TRAINING_SPLITS
        }
    )
    if leaked:
        named = ", ".join(
            f"{oid} (stored as {stored}, catalogue {listed})" for oid, stored, listed in leaked
        )
        raise ValueError(
            f"the dataset trains on object(s) the partnet catalogue holds out: {named}"
        )
