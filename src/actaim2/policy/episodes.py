"""The sim loop's bookkeeping, without ROS: which episodes run, how one is judged, what is recorded.

* :func:`plan_episodes` - episode k runs object ``k mod n`` (object folders when given, else
  every category x instance) with cluster ``clusters[(k div n) mod len(clusters)]`` and seed
  ``seed + k``: every object is visited before the next cluster, so a short run covers the objects.
* :func:`catalogue_paths` - the object folders of the partnet catalogue's splits.
* :func:`largest_change` - the paper's success criterion against what ``/reset_scene`` returned
  (``dof_initial`` and the limits): the largest |DoF change| as a fraction of its range.
* :class:`EpisodeRecord` - one JSON line per episode (``EpisodeLog``); :func:`summary_table`
  the per-object, per-cluster sample success rate (SSR) that ends a run.
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from actaim2.sim.success import SUCCESS_FRACTION, moved_fraction


@dataclass(frozen=True)
class EpisodeSpec:
    index: int
    category: str  # empty when object_path is set
    instance: int  # -1: drawn by the simulator from the seed
    object_path: str  # a PartNet-Mobility folder, overrides category/instance
    cluster: int  # requested from /sample_mode; -1 = sample from the learned prior
    seed: int


def plan_episodes(episodes: int, categories: Sequence[str], instances: Sequence[int], object_paths: Sequence[str],
                  clusters: Sequence[int], seed: int) -> list[EpisodeSpec]:
    folders = [p for p in object_paths if p]
    objects = [("", -1, p) for p in folders] or [(c, int(i), "") for c in categories for i in instances]
    if not objects:
        raise ValueError("no object to run: give categories (and instances) or object_paths")
    if not clusters:
        raise ValueError("no cluster to run: give clusters (-1 samples one from the learned prior)")
    return [EpisodeSpec(k, *objects[k % len(objects)], int(clusters[(k // len(objects)) % len(clusters)]), seed + k)
            for k in range(episodes)]


def catalogue_paths(catalogue_name: str, root: str, splits: Sequence[str]) -> list[str]:
    """Object folders to run: none for the generated catalogue (categories x instances name its
    objects), the partnet catalogue's folders of ``splits`` (at ``root``, "" = $ACTAIM2_PARTNET).
    Test splits are refused: they run only under the evaluation protocol (evaluate --final)."""
    from actaim2.data.real_objects import catalogue_folders, partnet_root
    from actaim2.data.splits import PARTNET, catalogue

    chosen = tuple(s for s in splits if s)
    if catalogue(catalogue_name) is not PARTNET:
        if chosen:
            raise ValueError(f"splits {list(chosen)} are for the partnet catalogue; the generated "
                             f"one's objects are categories x instances")
        return []
    tests = [s for s in chosen if s in PARTNET.test]
    if tests:
        raise ValueError(f"splits {tests} are test splits: they run only under the evaluation "
                         f"protocol (actaim2 evaluate --final, docs/evaluation.md)")
    where = partnet_root(Path(root) if root else None)
    folders = catalogue_folders(where, chosen or PARTNET.default_evaluate)
    return [f.folder for f in folders]


def largest_change(dof_names: Sequence[str], initial: Sequence[float], lower: Sequence[float], upper: Sequence[float],
                   state_names: Sequence[str], state_positions: Sequence[float]) -> float:
    """max |DoF change| / range over the object's DoFs; ValueError when the state lacks one of them."""
    index = {name: i for i, name in enumerate(state_names)}
    missing = [n for n in dof_names if n not in index]
    if missing:
        raise ValueError(f"/object_state lacks the DoF(s) {missing} of the reset object")
    current = np.asarray(state_positions, float)[[index[n] for n in dof_names]]
    return float(np.max(np.abs(moved_fraction(np.asarray(initial, float), current, lower, upper)), initial=0.0))


def is_success(change: float) -> bool:
    return change > SUCCESS_FRACTION


@dataclass
class PhaseRecord:
    phase: int
    keypose: dict  # actaim2.keypose.Keypose.to_json()
    confidence: float  # -1 for the sampler
    observation_stamp: float  # s (sim): the views (or cloud) the keypose came from
    not_before: float  # s (sim): end of the previous motion (the reset for INIT)
    executed: bool
    message: str  # ExecuteKeypose result message
    position_error: float = float("nan")  # m
    orientation_error: float = float("nan")  # rad
    candidate: int = 0  # the one executed (``keypose``): 0 the prediction, i its i-th fallback; -1 none


@dataclass
class EpisodeRecord:
    episode: int
    keyposes: str  # "policy" | "sampler"
    category: str
    instance: int
    object_path: str
    seed: int
    requested_cluster: int
    object_id: str = ""
    reset_stamp: float = float("nan")  # s (sim): observations from here on show the new scene
    cluster: int = -1  # the cluster used
    cluster_probabilities: list[float] = field(default_factory=list)
    mode_observation_stamp: float = float("nan")  # s (sim): the views the mode was sampled from
    phases: list[PhaseRecord] = field(default_factory=list)
    largest_change: float = 0.0  # fraction of the DoF's range
    success: bool = False
    note: str = ""  # why it failed, or where the motion stopped
    seconds: float = 0.0  # wall time of the episode, from the moment its servers were all there

    def to_json(self) -> dict:
        """Plain JSON types; NaN (not measured) becomes null, as strict JSON readers need."""
        return _strict(asdict(self))


def _strict(value):
    if isinstance(value, float) and not np.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    if isinstance(value, np.generic):
        return _strict(value.item())
    return value


class EpisodeLog:
    """Appends one JSON line per episode and flushes it, so an interrupted run keeps what it did."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.path.write_text("")

    def append(self, record: EpisodeRecord) -> None:
        with open(self.path, "a") as f:
            f.write(json.dumps(record.to_json()) + "\n")


def summary_table(records: Sequence[EpisodeRecord]) -> str:
    """Markdown: SSR per (object, cluster used) and overall."""
    groups: dict[tuple[str, int], list[bool]] = {}
    for r in records:
        groups.setdefault((r.object_id or r.object_path or r.category, r.cluster), []).append(r.success)
    lines = ["| object | cluster | episodes | successes | SSR |", "|---|---|---|---|---|"]
    for (obj, cluster), outcomes in sorted(groups.items()):
        lines.append(f"| {obj} | {cluster} | {len(outcomes)} | {sum(outcomes)} | {100 * sum(outcomes) / len(outcomes):.0f} % |")
    total = [r.success for r in records]
    rate = f"{100 * sum(total) / len(total):.0f} %" if total else "-"
    lines.append(f"| all | | {len(total)} | {sum(total)} | {rate} |")
    return "\n".join(lines)
