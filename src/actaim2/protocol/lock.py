"""The evaluation protocol's machinery: the lock that freezes a recipe before a test split is run,
and the ledger of every run on a test split (docs/evaluation.md, "Protocol").

``results/protocol.lock`` (JSON, committed before any test figure) holds:

* ``recipe``: the file that makes a checkpoint (training YAML, collection and training command
  script, ...) and its sha256;
* ``checkpoints``: the weights sha256 of each seed's checkpoint, seed 0's (the committed one)
  first;
* ``eval_set_version``: the evaluation set (``evalset.EVAL_SET_VERSION``) whose scenes are run;
* ``samples_per_group``: samples per cluster and per pseudo-cluster of every test run;
* ``objects``: per test split, the folder names of its objects (the partnet catalogue's);
* ``success_rule``: the rule that decides an outcome (:func:`success_rule`).

``actaim2 evaluate`` and ``actaim2 validate`` refuse an object of a test split (named by split, or
a folder a known splits file puts in one) unless given ``--final`` and a lock that matches the
run: its checkpoint among the lock's, the same evaluation set, samples per group and success
rule, and exactly the lock's objects of each test split run (none dropped, none added). Every
``--final`` run appends a line to ``results/ledger.jsonl``; ``actaim2 protocol ledger`` counts
them.
"""

from __future__ import annotations

import datetime
import hashlib
import json
import re
import shlex
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

from actaim2.data.splits import TEST_SPLITS

LOCK_FILE = Path("results/protocol.lock")
LEDGER_FILE = Path("results/ledger.jsonl")
_SHA256 = re.compile(r"[0-9a-f]{64}")
MIN_SEEDS = 3  # checkpoints of a lock: collection seed and training seed both varied


def success_rule() -> dict:
    """The success rule in force: some DoF moved (either way) by more than ``fraction`` of its
    range; a continuous joint (wheel, knob) counts with the range ``continuous_range`` (one
    turn)."""
    from actaim2.sim.objects.partnet import CONTINUOUS_RANGE
    from actaim2.sim.success import SUCCESS_FRACTION

    return {
        "rule": "some DoF moved by more than fraction x its range, every movable joint counts",
        "fraction": SUCCESS_FRACTION,
        "continuous_range": [float(v) for v in CONTINUOUS_RANGE],
    }


def file_sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@dataclass(frozen=True)
class ProtocolLock:
    """A frozen recipe and what its test runs must be (module docstring)."""

    recipe: str  # the recipe file, as given
    recipe_sha256: str
    checkpoints: tuple[str, ...]  # weights sha256 per seed, seed 0 first
    eval_set_version: int
    samples_per_group: int
    objects: dict[str, tuple[str, ...]]  # test split -> folder names
    success_rule: dict

    def __post_init__(self) -> None:
        if not self.recipe or not _SHA256.fullmatch(self.recipe_sha256):
            raise ValueError(
                f"a lock needs a recipe file and its sha256, got {self.recipe!r} "
                f"{self.recipe_sha256!r}"
            )
        bad = [c for c in self.checkpoints if not _SHA256.fullmatch(str(c))]
        if not self.checkpoints or bad:
            raise ValueError(
                "a lock needs each seed's checkpoint weights sha256 (64 hex digits); got "
                f"{list(self.checkpoints)}"
            )
        if len(set(self.checkpoints)) != len(self.checkpoints):
            raise ValueError("two seeds of the lock have the same checkpoint")
        if len(self.checkpoints) < MIN_SEEDS:
            raise ValueError(f"a lock needs at least {MIN_SEEDS} seeds' checkpoints, got "
                             f"{len(self.checkpoints)}")
        if self.samples_per_group < 2:
            raise ValueError(
                f"samples_per_group {self.samples_per_group}: the 2nd-mode rule needs >= 2 (both "
                "halves)"
            )
        unknown = sorted(set(self.objects) - set(TEST_SPLITS))
        if not self.objects or unknown or not all(self.objects.values()):
            raise ValueError(
                f"a lock lists the objects of test splits {TEST_SPLITS}, each split non-empty; "
                f"got {sorted(self.objects)}"
            )
        if not isinstance(self.success_rule, dict) or not self.success_rule:
            raise ValueError("a lock records the success rule")

    def to_json(self) -> dict:
        out = asdict(self)
        out["checkpoints"] = list(self.checkpoints)
        out["objects"] = {s: list(v) for s, v in sorted(self.objects.items())}
        return out

    @property
    def sha256(self) -> str:
        """Digest of the lock's content (the ledger names the lock a run was checked against)."""
        return hashlib.sha256(json.dumps(self.to_json(), sort_keys=True).encode()).hexdigest()

    @classmethod
    def read(cls, path: Path) -> ProtocolLock:
        try:
            data = json.loads(Path(path).read_text())
            return cls(
                str(data["recipe"]),
                str(data["recipe_sha256"]),
                tuple(data["checkpoints"]),
                int(data["eval_set_version"]),
                int(data["samples_per_group"]),
                {str(s): tuple(map(str, v)) for s, v in data["objects"].items()},
                dict(data["success_rule"]),
            )
        except FileNotFoundError:
            raise ValueError(
                f"no protocol lock at {path}: write one with `actaim2 protocol lock` and commit "
                "it "
                f"before a test split is run"
            ) from None
        except (json.JSONDecodeError, KeyError, TypeError, AttributeError) as exc:
            raise ValueError(f"{path}: not a protocol lock ({exc!r})") from None

    def write(self, path: Path) -> None:
        path = Path(path)
        if path.exists():
            raise ValueError(
                f"{path} exists: a lock is written once; a new recipe is a new protocol (remove "
                "it "
                f"deliberately, in its own commit, saying why)"
            )
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_json(), indent=2, sort_keys=True) + "\n")


def guarded_ids(splits_files: list[Path]) -> dict[str, str]:
    """folder name -> test split, over the splits files that exist among ``splits_files``."""
    from actaim2.data.real_objects import read_object_splits

    out: dict[str, str] = {}
    for path in splits_files:
        if Path(path).is_file():
            out.update(
                {
                    name: split
                    for name, split in read_object_splits(path).items()
                    if split in TEST_SPLITS
                }
            )
    return out


def protected(objects: list[tuple[str, str]], test_ids: dict[str, str]) -> dict[str, set[str]]:
    """test split -> the folder names among ``objects`` ((split, folder name or "")) that are
    in it: by their split, or by a folder a splits file puts in a test split (a split named with no
    folder gives its key with no name)."""
    out: dict[str, set[str]] = {}
    for split, name in objects:
        test_split = split if split in TEST_SPLITS else test_ids.get(name) if name else None
        if test_split is not None:
            out.setdefault(test_split, set()).update({name} - {""})
    return out


def check_run(
    tool: str,
    guarded: dict[str, set[str]],
    final: bool,
    lock_path: Path,
    checkpoints: list[str],
    eval_set_version: int | None = None,
    samples_per_group: int | None = None,
) -> ProtocolLock | None:
    """The lock a ``--final`` run is checked against (None for a run with no test object);
    ValueError saying what is missing or differs. ``guarded``: :func:`protected` of the run's
    objects; ``checkpoints``: the weights sha256 of the policies it runs; the two last are
    evaluate's."""
    if not guarded:
        if final:
            raise ValueError(
                f"--final is for test splits ({', '.join(TEST_SPLITS)}) only; this run has no "
                "test object"
            )
        return None
    named = "; ".join(
        f"{s}: {', '.join(sorted(v)) if any(v) else 'by split name'}"
        for s, v in sorted(guarded.items())
    )
    if not final:
        raise ValueError(
            f"{tool} refuses test-split objects ({named}) without --final and a matching protocol "
            "lock "
            f"({lock_path}): every choice is made on val; a test split runs once, under the lock "
            f"(docs/evaluation.md, Protocol)"
        )
    lock = ProtocolLock.read(lock_path)
    problems = []
    stray = [c for c in checkpoints if c not in lock.checkpoints]
    if stray or not checkpoints:
        problems.append(
            f"checkpoint(s) {stray or 'none'} are not among the lock's seeds "
            f"{list(lock.checkpoints)}"
        )
    if eval_set_version is not None and eval_set_version != lock.eval_set_version:
        problems.append(
            f"evaluation set version {eval_set_version}, the lock's is {lock.eval_set_version}"
        )
    if samples_per_group is not None and samples_per_group != lock.samples_per_group:
        problems.append(
            f"{samples_per_group} samples per group, the lock's is {lock.samples_per_group}"
        )
    if success_rule() != lock.success_rule:
        problems.append(f"success rule {success_rule()}, the lock's is {lock.success_rule}")
    for split, names in sorted(guarded.items()):
        locked = set(lock.objects.get(split, ()))
        if names != locked:
            problems.append(
                f"split {split}: objects differ from the lock's (missing "
                f"{sorted(locked - names)}, "
                f"not locked {sorted(names - locked)})"
            )
    if problems:
        raise ValueError(
            f"{tool} --final: the run does not match {lock_path}: " + "; ".join(problems)
        )
    return lock


def append_ledger(
    path: Path,
    lock: ProtocolLock,
    tool: str,
    out: str,
    guarded: dict[str, set[str]],
    checkpoints: list[str],
    samples: int,
) -> dict:
    """One line per ``--final`` run, written before it runs anything: when, what, against which
    lock, and ``samples``: the samples (evaluate) or trajectories (validate) it is to run;
    returns the line."""
    argv = sys.argv[1:] if sys.argv[1:2] == [tool] else [tool, "(called from Python)"]
    line = {
        "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "tool": tool,
        "command": "actaim2 " + " ".join(shlex.quote(a) for a in argv),
        "out": out,
        "lock_sha256": lock.sha256,
        "checkpoints": checkpoints,
        "splits": {s: sorted(v) for s, v in sorted(guarded.items())},
        "samples": samples,
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as f:
        f.write(json.dumps(line, sort_keys=True) + "\n")
    return line


def read_ledger(path: Path) -> list[dict]:
    """The ledger's runs ([] when there is none yet); ValueError naming a line that is not JSON."""
    path = Path(path)
    if not path.exists():
        return []
    runs = []
    for number, text in enumerate(path.read_text().splitlines(), 1):
        if text.strip():
            try:
                runs.append(json.loads(text))
            except json.JSONDecodeError:
                raise ValueError(f"{path}:{number}: not a JSON line") from None
    return runs
