"""Dataset splits by object, never by trajectory: the simulator catalogue's splits.

The catalogue (``actaim2.sim.objects.catalog.SPLITS``) fixes, as in the paper, training
categories with seen instances (``train_seen``) and unseen instances (``train_unseen_instance``)
and held-out categories (``heldout_category``). Every trajectory carries its object's split, so
no instance is ever on two sides; :func:`check_no_leak` verifies a stored index.
The training split also trains the default encoder, calibrates the success threshold and is the
evaluation's "seen objects". ``train_extra`` holds more instances of the training categories that
training uses when a dataset has them (:data:`TRAINING_SPLITS`) and no evaluation does: more
objects to learn from without changing the evaluation set.
"""
from __future__ import annotations

from actaim2.sim.objects.catalog import SPLITS

TRAIN = "train_seen"
UNSEEN_INSTANCE = "train_unseen_instance"
EXTRA_TRAIN = "train_extra"
UNSEEN_CATEGORY = "heldout_category"
TRAINING_SPLITS = (TRAIN, EXTRA_TRAIN)  # what the models train on; only TRAIN calibrates and is evaluated


def split_of(category: str, instance: int) -> str:
    """The catalogue split holding (category, instance); an uncatalogued object is an error."""
    found = [name for name, members in SPLITS.items() if instance in members.get(category, ())]
    if len(found) != 1:
        raise ValueError(f"object ({category!r}, {instance}) is in catalogue splits {found}, expected exactly one")
    return found[0]


def check_no_leak(entries: list[dict]) -> None:
    """Raise if an object is in two splits, or a held-out category shares objects with training."""
    by_object: dict[str, str] = {}  # by object id: real folders all have instance -1
    by_category: dict[str, set[str]] = {}
    for e in entries:
        key = e["object_id"]
        if by_object.setdefault(key, e["split"]) != e["split"]:
            raise ValueError(f"object {key} is in splits {by_object[key]!r} and {e['split']!r}")
        by_category.setdefault(e["category"], set()).add(e["split"])
    for category, splits in by_category.items():
        if UNSEEN_CATEGORY in splits and len(splits) > 1:
            raise ValueError(f"category {category!r} is held out but also in splits {sorted(splits - {UNSEEN_CATEGORY})}")
