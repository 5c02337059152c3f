"""Dataset splits by object, never by trajectory: the two object catalogues and their splits.

Two catalogues give objects per split (:data:`CATALOGUES`), with disjoint split names, so a
trajectory's split says which catalogue's rule put it there:

* ``generated`` (``actaim2.sim.objects.catalog.SPLITS``): as in the paper, training categories
  with seen instances (``train_seen``) and unseen instances (``train_unseen_instance``) and
  held-out categories (``heldout_category``); ``train_extra`` holds more instances of the
  training categories that training uses when a dataset has them and no evaluation does.
* ``partnet``: real PartNet-Mobility folders, split by the ``splits.yaml`` of the folder that
  holds them (``actaim2.data.real_objects``): ``train``, ``val`` (every choice of recipe and
  checkpoint), ``test_unseen_instance`` and ``test_unseen_category`` (run once a recipe is
  frozen, under the evaluation protocol: ``actaim2.protocol.lock``) and ``extra`` (other
  categories, optional training data).

Every trajectory carries its object's split, so no instance is ever on two sides;
:func:`check_no_leak` verifies a stored index. The models train on :data:`TRAINING_SPLITS` only;
the default encoder and the success label's threshold learn from :data:`CALIBRATION_SPLITS`
only, which are also the evaluation's "seen objects".
"""
from __future__ import annotations

from dataclasses import dataclass

from actaim2.sim.objects.catalog import SPLITS

TRAIN = "train_seen"
UNSEEN_INSTANCE = "train_unseen_instance"
EXTRA_TRAIN = "train_extra"
UNSEEN_CATEGORY = "heldout_category"
PARTNET_TRAIN = "train"
PARTNET_VAL = "val"
PARTNET_TEST_INSTANCE = "test_unseen_instance"
PARTNET_TEST_CATEGORY = "test_unseen_category"
PARTNET_EXTRA = "extra"


@dataclass(frozen=True)
class Catalogue:
    """A catalogue's split names and what each is for."""

    name: str
    splits: tuple[str, ...]  # every split, in the order tables show them
    training: tuple[str, ...]  # the models train on these when a dataset holds them
    calibration: str  # trains the encoder, calibrates the success label; "seen objects"
    validation: tuple[str, ...]  # every choice (recipe, epochs, checkpoint) is made on these
    test: tuple[str, ...]  # run only under a protocol lock (actaim2.protocol.lock)
    default_collect: tuple[str, ...]  # what `actaim2 collect` collects on by default
    default_evaluate: tuple[str, ...]  # what `actaim2 evaluate` and `validate` measure by default

    def __post_init__(self) -> None:
        named = {*self.training, *self.validation, *self.test, self.calibration,
                 *self.default_collect, *self.default_evaluate}
        if not named <= set(self.splits):
            raise ValueError(f"catalogue {self.name}: a role names a split outside {self.splits}")
        held_out = set(self.validation + self.test)
        if held_out & set(self.training) or self.calibration not in self.training:
            raise ValueError(f"catalogue {self.name}: training splits overlap held-out ones, or "
                             f"calibration is not a training split")

    def check_splits(self, names: tuple[str, ...], what: str) -> tuple[str, ...]:
        """``names`` if each is a split of this catalogue; ValueError naming the others."""
        unknown = [n for n in names if n not in self.splits]
        if unknown:
            raise ValueError(f"{what}: {unknown} are not splits of the {self.name} catalogue "
                             f"({', '.join(self.splits)})")
        return names


GENERATED = Catalogue(
    "generated", (TRAIN, UNSEEN_INSTANCE, UNSEEN_CATEGORY, EXTRA_TRAIN, "real_robot"),
    training=(TRAIN, EXTRA_TRAIN), calibration=TRAIN, validation=(), test=(),
    default_collect=(TRAIN, UNSEEN_INSTANCE, UNSEEN_CATEGORY),
    default_evaluate=(TRAIN, UNSEEN_INSTANCE, UNSEEN_CATEGORY))
PARTNET = Catalogue(
    "partnet",
    (PARTNET_TRAIN, PARTNET_VAL, PARTNET_TEST_INSTANCE, PARTNET_TEST_CATEGORY, PARTNET_EXTRA),
    training=(PARTNET_TRAIN, PARTNET_EXTRA), calibration=PARTNET_TRAIN, validation=(PARTNET_VAL,),
    test=(PARTNET_TEST_INSTANCE, PARTNET_TEST_CATEGORY), default_collect=(PARTNET_TRAIN,),
    default_evaluate=(PARTNET_VAL,))
CATALOGUES = {c.name: c for c in (GENERATED, PARTNET)}
TRAINING_SPLITS = GENERATED.training + PARTNET.training  # what the models train on
CALIBRATION_SPLITS = (GENERATED.calibration, PARTNET.calibration)
TEST_SPLITS = GENERATED.test + PARTNET.test


def catalogue(name: str) -> Catalogue:
    """The catalogue called ``name``; ValueError listing the known ones."""
    if name not in CATALOGUES:
        raise ValueError(f"unknown catalogue {name!r}; catalogues are {list(CATALOGUES)}")
    return CATALOGUES[name]


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
    held_out = {UNSEEN_CATEGORY, PARTNET_TEST_CATEGORY}
    for category, splits in by_category.items():
        if splits & held_out and splits - held_out:
            raise ValueError(f"category {category!r} is held out but also in splits "
                             f"{sorted(splits - held_out)}")
