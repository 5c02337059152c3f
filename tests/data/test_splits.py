"""Splits come from the catalogue, by object: an instance or a held-out category never leaks."""
from __future__ import annotations

import pytest

from actaim2.data.splits import TRAIN, UNSEEN_CATEGORY, UNSEEN_INSTANCE, check_no_leak, split_of
from actaim2.sim.objects.catalog import HELDOUT_CATEGORIES, TRAIN_CATEGORIES, split_instances


def test_every_catalogued_object_has_exactly_one_split():
    for split in (TRAIN, UNSEEN_INSTANCE, UNSEEN_CATEGORY):
        for category, instance in split_instances(split):
            assert split_of(category, instance) == split
    assert {c for c, _ in split_instances(UNSEEN_CATEGORY)} == set(HELDOUT_CATEGORIES)
    assert {c for c, _ in split_instances(TRAIN)} == set(TRAIN_CATEGORIES)
    with pytest.raises(ValueError):
        split_of("storage_furniture", 999)


def test_leaks_are_detected():
    ok = [{"category": c, "instance": i, "split": split_of(c, i)} for s in (TRAIN, UNSEEN_INSTANCE, UNSEEN_CATEGORY) for c, i in split_instances(s)]
    check_no_leak(ok + ok)
    with pytest.raises(ValueError, match="in splits"):
        check_no_leak(ok + [{"category": "door", "instance": 0, "split": UNSEEN_INSTANCE}])
    with pytest.raises(ValueError, match="held out"):
        check_no_leak([{"category": "safe", "instance": 0, "split": UNSEEN_CATEGORY}, {"category": "safe", "instance": 9, "split": TRAIN}])
