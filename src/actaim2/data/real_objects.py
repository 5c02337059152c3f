"""PartNet-Mobility folders as collection objects: their category and their split.

``actaim2 collect --objects DIR`` collects on every object folder in DIR (a folder of object
folders, or one). Objects are keyed by folder name; their category is meta.json's
``model_cat`` in the catalogue's spelling (:func:`actaim2.sim.objects.partnet.category_name`).

Split of each folder: the YAML given with ``--object-splits`` (``folder name: split``) where
it names the folder, else by category, as the catalogue splits its own objects:

* a catalogue training category (``TRAIN_CATEGORIES``): ``train_seen`` or
  ``train_unseen_instance``, half and half, fixed per folder by the CRC-32 of its name (so a
  folder keeps its split whatever else is collected);
* any other category (the catalogue's held-out ones, and categories the catalogue does not
  have, such as ``oven``): ``heldout_category``.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path

import yaml

from actaim2.data.splits import TRAIN, UNSEEN_CATEGORY, UNSEEN_INSTANCE
from actaim2.sim.objects.catalog import TRAIN_CATEGORIES

SPLIT_NAMES = (TRAIN, UNSEEN_INSTANCE, UNSEEN_CATEGORY)


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
        raise ValueError(f"{path}: expected a mapping 'folder name: split', got {type(data).__name__}")
    bad = {str(k): v for k, v in data.items() if v not in SPLIT_NAMES}
    if bad:
        raise ValueError(f"{path}: splits must be one of {SPLIT_NAMES}; got {bad}")
    return {str(k): str(v) for k, v in data.items()}


def folder_objects(path: Path, splits: dict[str, str] | None = None) -> list[FolderObject]:
    """The object folders under ``path`` with their categories and splits (module docstring).
    Raises ObjectLoadError (a ValueError) for a folder that cannot be read."""
    from actaim2.sim.objects.partnet import read_object_folder
    from actaim2.sim.objects.prepare import find_object_folders

    splits = splits or {}
    out = []
    for folder in find_object_folders(path):
        info = read_object_folder(folder)
        split = splits.get(info.object_id) or split_by_category(info.category, info.object_id)
        out.append(FolderObject(str(info.folder), info.category, split))
    return out
