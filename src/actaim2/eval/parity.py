"""Parity of the library evaluation with the ROS loop (``actaim2 parity``): the same episodes, both ways.

Twenty fixed (object, seed, cluster) tuples: tuple i is the evaluation set's object
``i mod 15`` of the 15 quick objects (the first instance of every category in each split), its
scene seed is the evaluation's reset seed of slot ``i div 15`` (``evalset.reset_seed``), and it
asks the checkpoint for cluster ``i mod K``. Each tuple runs

* through the library (:func:`actaim2.eval.episode.run_sample`, what ``actaim2 evaluate`` runs), and
* through the node graph (``actaim2.eval.parity_graph``): episode_runner -> sim_node,
  fusion_node, policy_node, control_node, each in its own process, over DDS.

Both draw the scene and the mode from the same seed: the episode runner seeds /reset_scene and
/sample_mode with the episode's one seed, so the library sample here uses that seed for both
(:class:`ParityTask`; the evaluation proper draws its mode from a second, independent seed).
Outcomes agree when both say success or both say failure.
"""
from __future__ import annotations

from dataclasses import dataclass

from actaim2.eval.evalset import catalogue_objects
from actaim2.eval.tasks import EvalTask

PARITY_TUPLES = 20  # the fixed set
AGREEMENT_TARGET = 18  # of 20


@dataclass(frozen=True)
class ParityTask(EvalTask):
    """An ActAIM2 sample seeded as the episode runner seeds an episode: one seed for scene and mode."""

    @property
    def sample_seed(self) -> int:
        return self.reset_seed


def parity_tasks(clusters: int, n: int = PARITY_TUPLES) -> list[ParityTask]:
    """The first ``n`` of the fixed tuples for a checkpoint with ``clusters`` clusters."""
    if clusters <= 0:
        raise ValueError("parity needs a checkpoint whose mode selector has clusters (ActAIM2's CGMVAE)")
    objects = catalogue_objects(instances_per_category=1)
    return [ParityTask("actaim2", objects[i % len(objects)], i // len(objects), i % clusters, clusters) for i in range(n)]


def _cell(record: dict | None) -> str:
    if record is None:
        return "not run"
    if "error" in record:
        return f"error: {record['error']}"
    outcome = "success" if record["success"] else "failure"
    return f"{outcome} ({record['largest_change']:.0%}, {record['phases_executed']} phases)"


def agrees(library: dict | None, ros: dict | None) -> bool:
    return (library is not None and ros is not None and "error" not in library and "error" not in ros
            and bool(library["success"]) == bool(ros["success"]))


def parity_report(tasks: list[ParityTask], library: list[dict | None], ros: list[dict | None], header: list[str]) -> str:
    """The markdown table of both outcomes per tuple and the agreement count."""
    lines = header + ["", "| # | object | seed | cluster | library (evaluate) | ROS loop (episode_runner) | agree | ROS note |",
                      "|---|---|---|---|---|---|---|---|"]
    for i, (task, lib, node) in enumerate(zip(tasks, library, ros)):
        note = (node or {}).get("note", "").replace("|", "/")
        lines.append(f"| {i} | {task.obj.key} | {task.reset_seed} | {task.cluster} | {_cell(lib)} | {_cell(node)} | "
                     f"{'yes' if agrees(lib, node) else 'NO'} | {note} |")
    n = sum(agrees(lib, node) for lib, node in zip(library, ros))
    target = round(AGREEMENT_TARGET * len(tasks) / PARITY_TUPLES)
    lines += ["", f"**Agreement: {n} / {len(tasks)}** (target: at least {target} / {len(tasks)}, the issue's "
                  f"{AGREEMENT_TARGET} of {PARITY_TUPLES}): {'met' if n >= target else 'NOT met'}."]
    return "\n".join(lines) + "\n"
