"""Markdown tables of an evaluation's records: the paper's Table 1 (SSR), Table 2 (Mode SSR), the
appendix table of 3rd and 4th modes, what the 2nd mode's group did on half B (the mode, the 1st
mode, another, a failure, or no 2nd mode on the object), whether the groups select outcomes at all
(a permutation test, ``mode_dependence.py``), the SSR of each cluster (whether some clusters draw eps the
predictor cannot act on), the acceptance checks, and where samples stopped
(which phase the planner refused and why, and the SSR of the samples that ran all four phases:
whether a row loses to infeasible keyposes or to keyposes that run and move nothing).

Every cell is a pooled rate over the samples it covers, with its 95 % Wilson interval
(``stats.py``): a category cell pools the category's objects in the split, AVG pools the whole
split (every object has the same number of samples, so this is the mean over objects, and over
categories where they have equally many objects, as in the paper).
"""
from __future__ import annotations

from collections import defaultdict
from typing import Iterable, Sequence

from actaim2.eval.evalset import SPLIT_TITLES, SPLITS, TABLE_SPLITS
from actaim2.eval.methods import METHODS, NOT_REPRODUCED, PSEUDO_CLUSTERS
from actaim2.eval.outcome import NO_SAMPLE
from actaim2.keypose import PHASE_NAMES
from actaim2.metrics.mode_dependence import PERMUTATIONS, dependence_cells
from actaim2.metrics.mode_ssr import GroupSample, ModeResult, object_mode_ssr, pooled
from actaim2.metrics.stats import Rate
from actaim2.sim.objects.catalog import HELDOUT_CATEGORIES

PAPER_ORDER = ("faucet", "table", "storage_furniture", "door", "switch", "refrigerator") + HELDOUT_CATEGORIES
SHORT = {"storage_furniture": "storage", "refrigerator": "fridge"}
AVG = "AVG"
MODE_NAMES = {1: "1st", 2: "2nd", 3: "3rd", 4: "4th"}
# The paper's AVG columns (seen, unseen instances, unseen categories), for comparison only.
PAPER_SSR = {"actaim2": (48.6, 38.7, 32.4), "data_collection": (11.2, 12.2, 17.6), "goal_rvt": (47.8, 38.6, 29.8),
             "actaim_cvae": (33.3, 25.2, 31.5),
             # appendix table "less vision" (trained on depth / one RGB-D camera)
             "actaim2_depth": (45.9, 34.4, 27.0), "actaim2_single_view": (36.2, 24.8, 13.6)}
PAPER_MODE = {("actaim2", 1): (71.5, 61.4, 48.2), ("actaim2", 2): (27.0, 20.9, 6.9),
              ("goal_rvt", 1): (60.3, 52.7, 40.1), ("goal_rvt", 2): (33.6, 25.8, 6.9),
              ("vqvae_rvt", 1): (48.75, 39.4, 32.5), ("vqvae_rvt", 2): (0.0, 0.0, 0.0)}


def _splits(records: Sequence[dict]) -> list[str]:
    present = {r["split"] for r in records}
    return [s for s in TABLE_SPLITS if s in present]


def _categories(records: Sequence[dict], split: str) -> list[str]:
    present = {r["category"] for r in records if r["split"] == split}
    return [c for c in PAPER_ORDER if c in present] + sorted(present - set(PAPER_ORDER))


def ssr_cells(records: Iterable[dict]) -> dict[tuple[str, str, str], Rate]:
    """(method, split, category or AVG) -> SSR."""
    cells: dict[tuple[str, str, str], Rate] = defaultdict(lambda: Rate(0, 0))
    for r in records:
        one = Rate(int(bool(r["success"])), 1)
        cells[r["method"], r["split"], r["category"]] += one
        cells[r["method"], r["split"], AVG] += one
    return dict(cells)


def object_modes(records: Iterable[dict], modes: int = 4) -> dict[tuple[str, str], list[ModeResult]]:
    """(method, object) -> mode results of that object (``mode_ssr.object_mode_ssr``)."""
    samples: dict[tuple[str, str], list[GroupSample]] = defaultdict(list)
    for r in records:
        if r.get("group", -1) >= 0:
            samples[r["method"], r["object"]].append(GroupSample(r["group"], r["repetition"], tuple(r["mode"]) if r["mode"] else None))
    return {key: object_mode_ssr(s, modes, f"{key[0]}|{key[1]}") for key, s in samples.items()}


def mode_cells(records: Sequence[dict], modes: int = 4) -> dict[tuple[str, str, str, int], Rate]:
    """(method, split, category or AVG, mode rank) -> Mode SSR pooled over the objects."""
    where = {(r["method"], r["object"]): (r["split"], r["category"]) for r in records}
    groups: dict[tuple[str, str, str], list[list[ModeResult]]] = defaultdict(list)
    for (method, obj), results in object_modes(records, modes).items():
        split, category = where[method, obj]
        groups[method, split, category].append(results)
        groups[method, split, AVG].append(results)
    return {(m, s, c, rank): pooled(per_object, rank) for (m, s, c), per_object in groups.items() for rank in range(1, modes + 1)}


def repeated_groups(records: Sequence[dict]) -> list[dict]:
    """The records of the (method, object) pairs that drew some group twice or more.

    Why: Mode SSR chooses a mode's group on half of the group's samples and measures it on the
    other half, and the mutual information of groups drawn once each is the outcomes' entropy
    whatever the groups select (every permutation ties). A row with one sample per group (the
    random sampler at 8 per object) has neither, and is left out of those tables, not shown empty.
    """
    counts: dict[tuple[str, str, int], int] = defaultdict(int)
    for r in records:
        if r.get("group", -1) >= 0:
            counts[r["method"], r["object"], r["group"]] += 1
    kept = {(m, obj) for (m, obj, _), n in counts.items() if n >= 2}
    return [r for r in records if (r["method"], r["object"]) in kept]


def _header(categories: list[str]) -> list[str]:
    names = [SHORT.get(c, c) for c in categories] + [f"**{AVG}**", "samples"]
    return ["| method | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]


def ssr_table(records: Sequence[dict], methods: list[str]) -> list[str]:
    cells = ssr_cells(records)
    lines = []
    for split in _splits(records):
        categories = _categories(records, split)
        lines += ["", f"**{SPLIT_TITLES[split]}** (SSR %, 95 % Wilson interval)", ""] + _header(categories)
        for m in methods:
            if (m, split, AVG) not in cells:
                continue
            row = [cells.get((m, split, c), Rate(0, 0)).cell() for c in categories + [AVG]]
            lines.append(f"| {METHODS[m].title} | " + " | ".join(row) + f" | {cells[m, split, AVG].trials} |")
    return lines


def mode_table(records: Sequence[dict], methods: list[str], ranks: Sequence[int] = (1, 2)) -> list[str]:
    cells = mode_cells(records, max(ranks))
    lines = []
    for split in _splits(records):
        categories = _categories(records, split)
        lines += ["", f"**{SPLIT_TITLES[split]}** (Mode SSR %, 95 % Wilson interval over the half-B samples)", ""]
        lines += _header(categories)
        for m in methods:
            for rank in ranks:
                if (m, split, AVG, rank) not in cells:
                    continue
                suffix = f" ({PSEUDO_CLUSTERS} random pseudo-clusters)" if METHODS[m].grouping == "pseudo" else ""
                row = [cells.get((m, split, c, rank), Rate(0, 0)).cell() for c in categories + [AVG]]
                lines.append(f"| {METHODS[m].title}{suffix}, {MODE_NAMES[rank]} mode | " + " | ".join(row)
                             + f" | {cells[m, split, AVG, rank].trials} |")
    return lines


SECOND_MODE_OUTCOMES = ("2nd mode", "1st mode", "another mode", "failed", "no 2nd mode on the object")


def second_mode_table(records: Sequence[dict], methods: list[str]) -> list[str]:
    """Per method and split: the outcomes of the half-B samples that the 2nd-mode SSR counts.

    Why: a low 2nd-mode SSR has different causes - the chosen group fails (the predictor's skill),
    it executes the 1st mode (the groups do not separate the modes), or the object showed one
    mode only (its half-B samples count as 0). The counts say which. The last column is what a group
    that selects nothing would score: per object, the share of *all* its half-B samples that executed
    its 2nd mode, in place of the chosen group's (pooled with the same weights). A 2nd-mode SSR near
    it says the groups add nothing to the row's base rate of that mode, whatever the interval.
    """
    split_of = {(r["method"], r["object"]): r["split"] for r in records}
    half_b: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for r in records:
        if r.get("group", -1) >= 0 and r["repetition"] % 2 == 1:
            half_b[r["method"], r["object"]].append(r)
    counts: dict[tuple[str, str], dict[str, int]] = defaultdict(lambda: dict.fromkeys(SECOND_MODE_OUTCOMES, 0))
    chance: dict[tuple[str, str], float] = defaultdict(float)  # expected 2nd-mode successes of an unselected group
    for (method, obj), (first, second) in object_modes(records, 2).items():
        tally = counts[method, split_of[method, obj]]
        if second.mode is None:  # counted as the Mode SSR counts it: 0 of its per-group half-B samples
            tally["no 2nd mode on the object"] += second.rate.trials
            continue
        for r in (r for r in half_b[method, obj] if r["group"] == second.group):
            mode = tuple(r["mode"]) if r["mode"] else None
            tally["failed" if mode is None else "2nd mode" if mode == second.mode else "1st mode" if mode == first.mode
                  else "another mode"] += 1
        every = half_b[method, obj]
        share = sum(r["mode"] is not None and tuple(r["mode"]) == second.mode for r in every) / len(every)
        chance[method, split_of[method, obj]] += share * second.rate.trials
    columns = SECOND_MODE_OUTCOMES + ("2nd mode of an unselected group (chance)",)
    lines = ["| method | split | " + " | ".join(columns) + " |", "|---" * (len(columns) + 2) + "|"]
    for m in methods:
        for split in (s for s in _splits(records) if (m, s) in counts):
            tally = counts[m, split]
            total = max(1, sum(tally.values()))
            lines.append(f"| {METHODS[m].title} | {SPLIT_TITLES[split]} | "
                         + " | ".join(f"{tally[k]} ({100 * tally[k] / total:.0f} %)" for k in SECOND_MODE_OUTCOMES)
                         + f" | {100 * chance[m, split] / total:.1f} % |")
    return lines


def many_modes_table(records: Sequence[dict], methods: list[str]) -> list[str]:
    """Per object, modes 1-4, for the objects whose successes showed three or more distinct outcomes."""
    per_object = object_modes(records, 4)
    where = {(r["method"], r["object"]): (r["split"], r["category"]) for r in records}
    lines = ["| method | split | category | object | 1st mode | 2nd mode | 3rd mode | 4th mode |", "|---" * 8 + "|"]
    for (m, obj), results in sorted(per_object.items(), key=lambda kv: (methods.index(kv[0][0]), kv[0][1])):
        if m not in methods or sum(r.mode is not None for r in results) < 3:
            continue
        split, category = where[m, obj]
        cells = [f"{100 * r.rate.value:.0f} ({r.rate.successes}/{r.rate.trials}) {r.mode[0]} {'+' if r.mode[1] > 0 else '-'}"
                 if r.mode is not None and r.rate.trials else "-" for r in results]
        lines.append(f"| {METHODS[m].title} | {SPLIT_TITLES[split]} | {category} | {obj} | " + " | ".join(cells) + " |")
    return lines if len(lines) > 2 else ["(no object showed three or more distinct modes)"]


def dependence_table(records: Sequence[dict], methods: list[str]) -> list[str]:
    """Per method drawing from groups and per split: MI(group; outcome) summed over objects, and its p-value."""
    cells, splits = dependence_cells(records), _splits(records)
    lines = ["| method | " + " | ".join(SPLIT_TITLES[s] for s in splits) + " |", "|---" * (len(splits) + 1) + "|"]
    for m in methods:
        if any((m, s) in cells for s in splits):
            suffix = f" ({PSEUDO_CLUSTERS} random pseudo-clusters)" if METHODS[m].grouping == "pseudo" else ""
            lines.append(f"| {METHODS[m].title}{suffix} | " + " | ".join(cells[m, s].cell() if (m, s) in cells else "-"
                                                                          for s in splits) + " |")
    return lines


def cluster_table(records: Sequence[dict], methods: list[str]) -> list[str]:
    """Per method asked for its K clusters (codes) and per split: the SSR of each cluster's samples and,
    after ``/``, the share of them that ran all four phases.

    Why: SSR draws the clusters uniformly, so a cluster whose eps the predictor cannot act on (one
    the selector's posterior never assigns a trajectory to, say) costs the row 1/K of its samples.
    """
    rows = [r for r in records if METHODS[r["method"]].grouping == "cluster" and r.get("group", -1) >= 0]
    if not rows:
        return ["(no row sampled by cluster)"]
    k = 1 + max(r["group"] for r in rows)
    lines = ["| method | split | " + " | ".join(f"cluster {c}" for c in range(k)) + " | samples |", "|---" * (k + 3) + "|"]
    for m in methods:
        for split in _splits(records):
            mine = [r for r in rows if r["method"] == m and r["split"] == split]
            if not mine:
                continue
            cells = []
            for c in range(k):
                group = [r for r in mine if r["group"] == c]
                ran = sum(r["phases_executed"] == len(PHASE_NAMES) for r in group)
                cells.append(f"{Rate(sum(bool(r['success']) for r in group), len(group)).cell()} / "
                             f"{100 * ran / len(group):.0f} %" if group else "-")
            lines.append(f"| {METHODS[m].title} | {SPLIT_TITLES[split]} | " + " | ".join(cells) + f" | {len(mine)} |")
    return lines


def _above(a: Rate | None, b: Rate | None) -> str:
    if a is None or b is None or not a.trials or not b.trials:
        return "not measured"
    return "holds" if a.interval[0] > b.interval[1] else "does not hold"


def acceptance_table(records: Sequence[dict]) -> list[str]:
    """The acceptance checks: ActAIM2's intervals above Data Collection's (SSR; 2nd mode vs pseudo-clusters)."""
    ssr, modes = ssr_cells(records), mode_cells(records, 2)
    lines = ["| check | ActAIM2 | Data Collection | interval above |", "|---|---|---|---|"]
    for split in (s for s in SPLITS[:2] if s in _splits(records)):
        a, b = ssr.get(("actaim2", split, AVG)), ssr.get(("data_collection", split, AVG))
        lines.append(f"| SSR, {SPLIT_TITLES[split]} | {a.cell() if a else '-'} | {b.cell() if b else '-'} | {_above(a, b)} |")
    for split in _splits(records):
        a, b = modes.get(("actaim2", split, AVG, 2)), modes.get(("data_collection", split, AVG, 2))
        lines.append(f"| 2nd-mode SSR, {SPLIT_TITLES[split]} (Data Collection in {PSEUDO_CLUSTERS} random pseudo-clusters) | "
                     f"{a.cell() if a else '-'} | {b.cell() if b else '-'} | {_above(a, b)} |")
    return lines


def stop_of(record: dict) -> tuple[str, str]:
    """(where, why) a sample ended: a phase name and the planner's reason, ``NO_SAMPLE``, or ("", "") when all four ran.

    Read from the note ``episode.run_sample`` writes: "PHASE: reason: message" for a refused keypose.
    """
    note = record.get("note") or ""
    if note.startswith(NO_SAMPLE):
        return NO_SAMPLE, ""
    if record["phases_executed"] == len(PHASE_NAMES) or not note:
        return "", ""
    phase, _, rest = note.partition(": ")
    return phase, rest.partition(": ")[0]


def stops_table(records: Sequence[dict], methods: list[str], reasons: int = 3) -> list[str]:
    """Per row, over every split: the share of samples ended at each phase by a refused keypose (or with no
    sample), the share that ran all four phases and those samples' SSR, the share that executed a fallback
    keypose in some phase (the record's ``candidate``), and the most frequent refusals."""
    where = [NO_SAMPLE, *PHASE_NAMES]
    lines = ["| method | samples | " + " | ".join(f"stopped at {w}" if w != NO_SAMPLE else w for w in where)
             + " | all four phases ran | SSR of those (%) | ran a fallback | most frequent refusals |",
             "|---" * (len(where) + 6) + "|"]
    for m in methods:
        rows = [r for r in records if r["method"] == m]
        if not rows:
            continue
        stops = [stop_of(r) for r in rows]
        ran = [r for r, (phase, _) in zip(rows, stops) if not phase]
        share = {w: sum(phase == w for phase, _ in stops) / len(rows) for w in where}
        counts: dict[tuple[str, str], int] = defaultdict(int)
        for phase, why in stops:
            if phase and phase != NO_SAMPLE:
                counts[phase, why] += 1
        top = sorted(counts.items(), key=lambda kv: -kv[1])[:reasons]
        lines.append(f"| {METHODS[m].title} | {len(rows)} | " + " | ".join(f"{100 * share[w]:.1f} %" for w in where)
                     + f" | {100 * len(ran) / len(rows):.1f} % | {Rate(sum(bool(r['success']) for r in ran), len(ran)).cell()} | "
                     + f"{100 * sum(max(r.get('candidate', [0]), default=0) > 0 for r in rows) / len(rows):.1f} % | "
                     + ", ".join(f"{phase} {why} {100 * n / len(rows):.1f} %" for (phase, why), n in top) + " |")
    return lines


def paper_table() -> list[str]:
    lines = ["| paper (AVG %) | seen | unseen instances | unseen categories |", "|---|---|---|---|"]
    lines += [f"| {METHODS[m].title}, SSR | " + " | ".join(f"{v:.1f}" for v in values) + " |" for m, values in PAPER_SSR.items()]
    lines += [f"| {METHODS[m].title}, {MODE_NAMES[k]} mode | " + " | ".join(f"{v:.1f}" for v in values) + " |"
              for (m, k), values in PAPER_MODE.items()]
    return lines


def report(records: Sequence[dict], methods: list[str], header: list[str]) -> str:
    """The whole markdown report: header lines (command, checkpoints), then every table."""
    done = [m for m in methods if any(r["method"] == m for r in records)]
    grouped = repeated_groups(records)
    once = [METHODS[m].title for m in done if not any(r["method"] == m for r in grouped)]
    without = f" Without Mode SSR (one sample per group): {', '.join(once)}." if once else ""
    lines = list(header)
    lines += ["", "## Table 1: sample success rate (SSR)"] + ssr_table(records, done)
    lines += ["", "## Table 2: Mode SSR (1st and 2nd modes)",
              "", "Mode SSR: modes ranked by their successes on half A of an object; each mode's cluster chosen on half A, "
                  f"its rate measured on half B (docs/evaluation.md).{without}"] + mode_table(grouped, done)
    lines += ["", "## Appendix: objects with more than two modes (Mode SSR of modes 1-4, half B)", ""]
    lines += many_modes_table(grouped, done)
    lines += ["", "## What the 2nd mode's group did on half B", "",
              "The half-B samples the 2nd-mode SSR counts (Table 2): each object's group chosen for its 2nd mode on "
              "half A, or, where the object showed one mode only, the samples it counts as 0.", ""]
    lines += second_mode_table(grouped, done)
    lines += ["", "## Do the groups select outcomes? (all samples, docs/evaluation.md)", "",
              "Mutual information (nats, summed over objects) between the group a sample was drawn from and its "
              f"outcome (mode of a success, or failed); p: permutation test, groups shuffled within each object "
              f"({PERMUTATIONS} permutations).", ""]
    lines += dependence_table(grouped, done)
    lines += ["", "## SSR per cluster", "",
              "SSR % [95 % Wilson] of each cluster's (code's) samples / the share of them that ran all four phases.", ""]
    lines += cluster_table(records, done)
    lines += ["", "## Acceptance checks", ""] + acceptance_table(records)
    lines += ["", "## Where samples stopped (all splits)", "",
              "A keypose the planner refuses, with every fallback given with it, ends its sample (docs/evaluation.md); "
              "the rest ran all four phases."]
    lines += [""] + stops_table(records, done)
    lines += ["", "## The paper's figures, for comparison", ""] + paper_table()
    lines += ["", "## Methods", ""] + [f"- **{METHODS[m].title}**: {METHODS[m].about}" for m in done]
    lines += [f"- **{name}**: not reproduced: {why}" for name, why in NOT_REPRODUCED.items()]
    return "\n".join(lines) + "\n"
