"""The three-drawer stand-in of the paper's real-robot result, in the simulator.

The demonstrations (``scripted_teleop`` through ``bag_recorder``, docs/finetuning.md) start from
three initial states of the three-drawer shelf: the bottom, middle or top drawer half-open, the
others shut (``rollout.teleop_eval.initial_state``). The evaluation asks a checkpoint for those
states at held-out placements:

  placements  ``reset_seed(SHELF, p)`` of :mod:`.evalset` for p = 0..N-1: at or above 2**31, so
              disjoint from the demonstrations' seeds (``1000 * drawer + episode``, below 3000)
              and from data collection's. One placement is one seed for its three states, every
              cluster and both checkpoints: the rows are compared on the same scenes.
  episodes    (placement, state, cluster, checkpoint), each run by ``actaim2 evaluate``'s episode
              (:func:`.episode.run_sample`: the mode of the asked cluster from the robot-hidden
              initial views, then four predicted keyposes executed as data collection executes them).
  verdicts    of the half-open drawer, by the scripted teleoperator's rule
              (:func:`actaim2.rollout.scripted_teleop.judged_success`): push succeeds when it moved
              more than 30 % of its range shut, pull when it moved more than 30 % open.
  modes       push (pull) asks for the cluster holding most labelled push (pull) demonstrations
              (``finetune``'s cluster table): N x 3 episodes per mode, 6N per checkpoint.
  clusters    every cluster asked on the same N x 3 states; its success is the drawer moving more
              than 30 % either way, with how often it was shut and how often opened. The mode rows
              are the episodes of their clusters here, judged by their own direction.

Rates carry 95 % Wilson intervals (:mod:`.stats`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from actaim2.eval.evalset import EvalObject, reset_seed
from actaim2.eval.tasks import EvalTask
from actaim2.eval.worker import EvalWorker
from actaim2.metrics.stats import Rate
from actaim2.rollout.teleop_eval import MODES, STATE_NAMES, initial_state

SPLIT = "standin"
SHELF = EvalObject(SPLIT, "three_drawer_shelf", 0)  # the demonstrations' shelf (scripted_teleop instance 0)
BOTH = "both"  # the push and pull episodes pooled


@dataclass(frozen=True)
class StandinTask(EvalTask):
    """One episode: ``method`` is the condition (before / after), ``slot`` numbers the initial state."""

    placement: int = 0
    drawer: int = 0  # the half-open one (index into STATE_NAMES)

    @property
    def key(self) -> str:
        return f"{self.method}|p{self.placement}|{STATE_NAMES[self.drawer]}|c{self.cluster}"

    @property
    def reset_seed(self) -> int:
        """The placement's seed: the same for its three initial states, every cluster and both checkpoints."""
        return reset_seed(self.obj, self.placement)

    @property
    def dof_fraction(self) -> list[float]:
        return initial_state(len(STATE_NAMES), self.drawer)


def placement_seeds(placements: int) -> list[int]:
    """The reset seed of each held-out placement."""
    return [reset_seed(SHELF, p) for p in range(placements)]


def plan_episodes(clusters: dict[str, Sequence[int]], k: dict[str, int], placements: int) -> list[StandinTask]:
    """The episodes of each condition (name -> the clusters to ask, its K), placement-major so that an interrupted
    run has covered the conditions and clusters about equally."""
    return [StandinTask(condition, SHELF, p * len(STATE_NAMES) + d, c, k[condition], placement=p, drawer=d)
            for p in range(placements) for d in range(len(STATE_NAMES))
            for condition, asked in clusters.items() for c in asked]


class StandinWorker(EvalWorker):
    """An evaluation worker whose episodes start from the task's initial state and carry the drawer's verdicts."""

    def sample(self, task: StandinTask) -> dict:
        from actaim2.rollout.expert import ExpertTask
        from actaim2.rollout.scripted_teleop import judged_success

        record = self.episode(task, task.dof_fraction)
        info, final = self.env.info, self.env.object_dof()
        dof = info.dof_names[task.drawer]
        verdicts, moved = {}, 0.0
        for mode, direction in MODES.items():
            verdicts[mode], moved = judged_success(ExpertTask(dof, direction), list(info.dof_names), info.dof_initial, final,
                                                   info.dof_lower, info.dof_upper)
        record.update(key=task.key, placement=task.placement, drawer=STATE_NAMES[task.drawer], dof=dof,
                      drawer_moved=round(moved, 5), verdicts=verdicts)
        return record


def mode_clusters(condition: str, finetune: dict | None, weights_sha256: str | None, k: int,
                  overrides: dict[str, int | None]) -> tuple[dict[str, int], str]:
    """(mode -> the cluster asked for it, where each came from) for ``condition``.

    ``finetune`` is the fine-tuned checkpoint's ``lineage.finetune``: after fine-tuning the label -> cluster map it
    was trained with (``mode_labels.label_cluster``, what ``/sample_mode`` serves a mode label by), else its ``after``
    cluster table; before it its ``before`` table (the same labelled demonstrations through the parent's selector, so
    each checkpoint is asked for the cluster its own selector puts the demonstrations in), usable only when the
    "before" checkpoint is that parent. ``overrides`` (mode -> cluster, None: not given) replace the tables'.
    """
    table: dict[str, int] = {}
    why_not = "no fine-tuned checkpoint (--after) with lineage.finetune"
    source = f"lineage.finetune.{condition}.clusters.label_cluster"
    if finetune is not None:
        parent = (finetune.get("parent") or {}).get("weights_sha256")
        trained = (finetune.get("mode_labels") or {}).get("label_cluster")
        if condition == "before" and parent != weights_sha256:
            why_not = f"the fine-tuned checkpoint's parent has weights {parent}, the before checkpoint {weights_sha256}"
        elif condition == "after" and trained:
            table, source = trained, "lineage.finetune.mode_labels.label_cluster"
        else:
            table = finetune[condition]["clusters"]["label_cluster"]
    chosen, sources = {}, []
    for mode in MODES:
        if overrides.get(mode) is not None:
            chosen[mode] = int(overrides[mode])
            sources.append(f"{mode}: --{mode}-cluster")
        elif mode in table:
            chosen[mode] = int(table[mode])
            sources.append(f"{mode}: {source}")
        else:
            raise ValueError(f"{condition}: no cluster for {mode} ({why_not if not table else f'no {mode} demonstration in the table'}): "
                             f"give --{mode}-cluster")
        if not 0 <= chosen[mode] < k:
            raise ValueError(f"{condition}: cluster {chosen[mode]} for {mode} is not one of the checkpoint's {k}")
    return chosen, "; ".join(sources)


def summarise(records: Sequence[dict], clusters: dict[str, int], k: int) -> dict:
    """One condition's rates: per mode (its cluster's episodes, judged by the mode's direction), per half-open drawer
    and pooled; per cluster (the drawer moved either way) with how often it was shut and opened."""
    modes: dict[str, dict[str, Rate]] = {}
    for mode, cluster in clusters.items():
        episodes = [r for r in records if r["requested_cluster"] == cluster]
        rows = {state: Rate(sum(r["verdicts"][mode] for r in episodes if r["drawer"] == state),
                            sum(r["drawer"] == state for r in episodes)) for state in STATE_NAMES}
        modes[mode] = {**rows, "all": Rate(sum(r["verdicts"][mode] for r in episodes), len(episodes))}
    modes[BOTH] = {row: sum((modes[m][row] for m in clusters), Rate(0, 0)) for row in (*STATE_NAMES, "all")}
    per_cluster = []
    for c in range(k):
        episodes = [r for r in records if r["requested_cluster"] == c]
        shut, opened = (sum(r["verdicts"][mode] for r in episodes) for mode in MODES)
        per_cluster.append({"cluster": c, "asked_for": [m for m, asked in clusters.items() if asked == c],
                            "moved": Rate(shut + opened, len(episodes)), "push": shut, "pull": opened})
    return {"modes": modes, "clusters": per_cluster}


def summary_json(summary: dict) -> dict:
    return {"modes": {m: {row: rate.to_json() for row, rate in rows.items()} for m, rows in summary["modes"].items()},
            "clusters": [{**c, "moved": c["moved"].to_json()} for c in summary["clusters"]]}


def _cell(rate: Rate) -> str:
    return f"{rate.successes}/{rate.trials}: {rate.cell()}" if rate.trials else "-"


def tables(summaries: dict[str, dict]) -> list[str]:
    """The Markdown tables of the conditions' summaries, side by side."""
    names = list(summaries)
    lines = ["## Push and pull", "",
             "The half-open drawer moved more than 30 % of its range the asked way (push: shut, pull: open); "
             "successes/episodes: percent [95 % Wilson interval].", "",
             "| half-open drawer | mode | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for mode in (*MODES, BOTH):
        for row in (*STATE_NAMES, "all"):
            cells = [_cell(summaries[n]["modes"][mode][row]) for n in names]
            lines.append(f"| {row} | {mode} | " + " | ".join(f"**{c}**" if row == "all" else c for c in cells) + " |")
    if not any(s["clusters"] for s in summaries.values()):
        return lines
    lines += ["", "## Each cluster on the same initial states", "",
              "The half-open drawer moved more than 30 % of its range either way; how often it was shut / opened; "
              "the mode the cluster is asked for.", "",
              "| cluster | " + " | ".join(f"{n}: moved | {n}: shut / opened" for n in names) + " |",
              "|---|" + "---|---|" * len(names)]
    for c in range(max(len(s["clusters"]) for s in summaries.values())):
        cells = []
        for n in names:
            row = summaries[n]["clusters"][c] if c < len(summaries[n]["clusters"]) else None
            asked = f" ({', '.join(row['asked_for'])})" if row and row["asked_for"] else ""
            cells += [_cell(row["moved"]) + asked, f"{row['push']} / {row['pull']}"] if row else ["-", "-"]
        lines.append(f"| c{c} | " + " | ".join(cells) + " |")
    return lines


# -- the self-filter under calibration errors (actaim2 bench standin-self-filter) --------

SHARES = {"arm": ("arm_left", "arm_pixels"), "near": ("near_removed", "near_pixels"),
          "object": ("near_object_removed", "near_object_pixels")}


def share(figures: dict, what: str) -> float:
    """The share of a figure's pixels: arm left, removed within 5 cm, or the object's removed (SHARES)."""
    part, whole = SHARES[what]
    return figures[part] / max(1, figures[whole])


def summary_table(samples: list[dict]) -> list[str]:
    """``actaim2 bench standin-self-filter``'s table. Markdown: per placement and observation, arm pixels left and non-arm pixels removed within 5 cm of the arm
    (all; the object's), nominal -> refined extrinsic, and the camera pose error; the worst of each last."""
    lines = ["| placement | drawer, mode | observation | arm pixels | arm left | removed within 5 cm "
             "| object removed within 5 cm | camera pose error | correction |", "|---" * 9 + "|"]
    for s in samples:
        b, a, e = s["before"], s["after"], s["pose_error"]
        lines.append(f"| {s['placement']} | {s['drawer']}, {s['mode']} | {s['observation']} | {b['arm_pixels']} "
                     f"| {share(b, 'arm'):.1%} -> {share(a, 'arm'):.1%} | {share(b, 'near'):.1%} -> {share(a, 'near'):.1%} "
                     f"| {share(b, 'object'):.2%} -> {share(a, 'object'):.2%} ({b['near_object_pixels']}) "
                     f"| {e['before']['mm']:.1f} mm / {e['before']['deg']:.2f} deg -> {e['after']['mm']:.1f} mm / "
                     f"{e['after']['deg']:.2f} deg | {s['correction_mm']:.1f} mm / {s['correction_deg']:.2f} deg"
                     f"{'' if s['refined'] else ' (refused)'} |")
    worst = {what: " -> ".join(f"{max(share(s[side], what) for s in samples):.{2 if what == 'object' else 1}%}"
                               for side in ("before", "after")) for what in SHARES}
    lines.append(f"| worst | | | | {worst['arm']} | {worst['near']} | {worst['object']} | | |")
    return lines
