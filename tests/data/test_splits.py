"""Splits come from the catalogue, by object: an instance or a held-out category never leaks."""
from __future__ import annotations

import pytest

from actaim2.data.splits import (
    EXTRA_TRAIN,
    TRAIN,
    UNSEEN_CATEGORY,
    UNSEEN_INSTANCE,
    check_no_leak,
    split_of,
)
from actaim2.sim.objects.catalog import (
    HELDOUT_CATEGORIES,
    TRAIN_CATEGORIES,
    object_id,
    split_instances,
)


def test_every_catalogued_object_has_exactly_one_split():
    for split in (TRAIN, UNSEEN_INSTANCE, UNSEEN_CATEGORY, EXTRA_TRAIN):
        for category, instance in split_instances(split):
            assert split_of(category, instance) == split
    assert {c for c, _ in split_instances(UNSEEN_CATEGORY)} == set(HELDOUT_CATEGORIES)
    assert {c for c, _ in split_instances(TRAIN)} == {c for c, _ in split_instances(EXTRA_TRAIN)} == set(TRAIN_CATEGORIES)
    with pytest.raises(ValueError):
        split_of("storage_furniture", 999)


def test_leaks_are_detected():
    def entry(category: str, instance: int, split: str, oid: str = "") -> dict:
        return {"object_id": oid or object_id(category, instance), "category": category, "instance": instance, "split": split}

    ok = [entry(c, i, split_of(c, i)) for s in (TRAIN, UNSEEN_INSTANCE, UNSEEN_CATEGORY) for c, i in split_instances(s)]
    check_no_leak(ok + ok)
    with pytest.raises(ValueError, match="in splits"):
        check_no_leak(ok + [entry("door", 0, UNSEEN_INSTANCE)])
    with pytest.raises(ValueError, match="held out"):
        check_no_leak([entry("safe", 0, UNSEEN_CATEGORY), entry("safe", 9, TRAIN)])
    # real folders (instance -1) are told apart by their folder names
    check_no_leak([entry("table", -1, TRAIN, "22241"), entry("table", -1, UNSEEN_INSTANCE, "19179")])
    with pytest.raises(ValueError, match="in splits"):
        check_no_leak([entry("table", -1, TRAIN, "22241"), entry("table", -1, UNSEEN_INSTANCE, "22241")])
