"""The tables ``actaim2 report`` writes into README.md and docs/, each from committed records.

Every table is computed by the evaluation's own code (``actaim2.eval.tables``: pooled rates with
Wilson intervals, split-half Mode SSR, the permutation test) over the records' samples; a table
naming several records pools their samples, so they must cover different (method, split) pairs.
Machine, cores and load average appear only as the records' fields (the ``runs`` table).
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from actaim2.data.splits import CALIBRATION_SPLITS
from actaim2.data.success import label_metrics
from actaim2.eval import tables as et
from actaim2.eval.evalset import SPLIT_TITLES, SPLITS
from actaim2.eval.methods import METHODS
from actaim2.eval.paired import comparison
from actaim2.eval.standin import summary_table
from actaim2.metrics.stats import Rate
from actaim2.report.records import Record, RecordError

PAPER_COLUMN = {split: i for i, split in enumerate(SPLITS)}  # the paper's AVG columns, in order


def _samples(records: Sequence[Record]) -> list[dict]:
    seen: dict[tuple[str, str], str] = {}
    samples = []
    for record in records:
        for pair in {(s["method"], s["split"]) for s in record.samples}:
            if pair in seen:
                raise RecordError(f"records {seen[pair]} and {record.name} both hold {pair[0]} "
                                  f"on {pair[1]}: a table pools its records, so none may overlap")
            seen[pair] = record.name
        samples += record.samples
    return samples


def _methods(samples: Sequence[dict]) -> list[str]:
    return [m for m in METHODS if any(s["method"] == m for s in samples)]


def _splits(samples: Sequence[dict]) -> list[str]:
    return [s for s in SPLITS if any(r["split"] == s for r in samples)]


def results_table(records: Sequence[Record]) -> list[str]:
    """The summary: each method's AVG SSR and 1st / 2nd-mode SSR per split, each beside the paper's
    figure; the paper's Data Collection SSR as the yardstick."""
    samples = _samples(records)
    splits, methods = _splits(samples), _methods(samples)
    ssr, modes = et.ssr_cells(samples), et.mode_cells(et.repeated_groups(samples), 2)
    label = {m: next(r.label for r in records if m in r.meta["checkpoints"]) for m in methods}
    columns = " | ".join(f"{SPLIT_TITLES[s]} | the paper" for s in splits)
    lines = [f"| AVG %, 95 % Wilson interval | {columns} |", "|---" * (2 * len(splits) + 1) + "|"]

    def paper(values: tuple[float, ...] | None, split: str) -> str:
        return f"{values[PAPER_COLUMN[split]]:.1f}" if values else "-"

    for m in methods:
        lines.append(f"| {label[m]}, SSR | " + " | ".join(
            f"{ssr[m, s, et.AVG].cell() if (m, s, et.AVG) in ssr else '-'} | "
            f"{paper(et.PAPER_SSR.get(m), s)}"
            for s in splits) + " |")
        for rank in (1, 2):
            lines.append(f"| {label[m]}, {et.MODE_NAMES[rank]} mode | " + " | ".join(
                f"{modes[m, s, et.AVG, rank].cell() if (m, s, et.AVG, rank) in modes else '-'} | "
                f"{paper(et.PAPER_MODE.get((m, rank)), s)}" for s in splits) + " |")
    lines.append(f"| {METHODS['data_collection'].title}, SSR | " + " | ".join(
        f"- | {paper(et.PAPER_SSR['data_collection'], s)}" for s in splits) + " |")
    return lines


def runs_table(records: Sequence[Record]) -> list[str]:
    """Where each record comes from: command, checkpoint and dataset digests, machine and load."""
    lines = ["| record | command | checkpoint (weights sha256) | dataset | samples | wall time "
             "| machine | cores | workers | load average | note |", "|---" * 11 + "|"]
    for r in records:
        m = r.meta
        checkpoints = ", ".join(f"{c['weights_sha256'][:16]}" for c in m["checkpoints"].values()) or "-"
        datasets = sorted({c["dataset_digest"] for c in m["checkpoints"].values()}
                          | ({m["dataset"].get("digest", m["dataset"]["path"])} if "dataset" in m else set()))
        lines.append(f"| `results/{r.name}` | `{m['command']}` | {checkpoints} "
                     f"| {', '.join(datasets)} | {m['samples']} | {m['seconds']} s "
                     f"| {m['machine']} | {m['cores']} | {m['workers']} | {m['load_average']:.1f} "
                     f"| {m.get('note') or '-'} |")
    return lines


def _evaluation(render: Callable[[list[dict], list[str]], list[str]], grouped: bool = False
                ) -> Callable[[Sequence[Record]], list[str]]:
    """A table of ``actaim2.eval.tables`` over the records' pooled samples."""
    def table(records: Sequence[Record]) -> list[str]:
        samples = _samples(records)
        methods = _methods(samples)
        lines = render(et.repeated_groups(samples) if grouped else samples, methods)
        return lines[1:] if lines and lines[0] == "" else lines
    return table


SAMPLERS = ("random", "grasp", "gmm")
MOVED = 0.05  # a trajectory "moved a part" when some DoF changed by more than this share of its range
COMPARE_HALVINGS, COMPARE_ROUNDS = 100, 2000  # the protocol's random halvings and bootstrap rounds
LABEL_TARGETS = {"accuracy": 0.95, "balanced_accuracy": 0.90}  # the visual label's targets on every split and category
# Bins of a trajectory's largest DoF change (share of the range), for those that touched the object.
CHANGE_BINS = ((0.0, 0.01), (0.01, MOVED), (MOVED, 0.3), (0.3, np.inf))


def _collected(records: Sequence[Record]) -> list[dict]:
    """The trajectories each sampler was asked for: a collection's top-ups (random trajectories
    past the random count, standing in for the ones another sampler gave up on) are left out,
    so every sampler is measured on the same objects at its own count."""
    samples = []
    for r in records:
        if r.meta.get("kind") != "collection":
            raise RecordError(f"record {r.name} is not a collection")
        counts = r.meta["dataset"]["info"]["per_object"]
        samples += [s for s in r.samples if _index(s) < counts.get(s["sampler"], 0)]
    return samples


def _index(sample: dict) -> int:
    """The trajectory's number among its sampler's on its object (ids end in ``-<number>``)."""
    return int(sample["id"].rsplit("-", 1)[1])


def _largest_change(sample: dict) -> float:
    return float(np.max(np.abs(sample["dof_change"]), initial=0.0))


def _by_category(samples: list[dict]) -> list[tuple[str, list[dict]]]:
    categories = sorted({s["category"] for s in samples})
    return [(c, [s for s in samples if s["category"] == c]) for c in categories] + [("all", samples)]


def samplers_table(records: Sequence[Record]) -> list[str]:
    """Per category: objects, and per sampler the ground-truth success (95 % Wilson interval,
    successes / executed trajectories) and the share of executed trajectories that moved a part
    by more than MOVED of its range; skipped trajectories (no feasible sample) are counted apart."""
    samples = _collected(records)
    samplers = [s for s in SAMPLERS if any(x["sampler"] == s for x in samples)]
    head = " | ".join(f"{s}: success % | {s}: moved > {MOVED:.0%} | {s}: skipped" for s in samplers)
    lines = [f"| category | objects | {head} |", "|---" * (2 + 3 * len(samplers)) + "|"]
    for category, rows in _by_category(samples):
        cells = []
        for sampler in samplers:
            done = [x for x in rows if x["sampler"] == sampler and not x.get("skipped")]
            rate = Rate(sum(bool(x["gt_success"]) for x in done), len(done))
            moved = sum(_largest_change(x) > MOVED for x in done)
            skipped = sum(x["sampler"] == sampler and bool(x.get("skipped")) for x in rows)
            cells.append(f"{rate.cell()} ({rate.successes}/{rate.trials}) | {100 * moved / len(done):.0f} % "
                         f"| {skipped}" if done else f"- | - | {skipped}")
        objects = len({x["object_id"] for x in rows if "object_id" in x})
        lines.append(f"| {category} | {objects} | " + " | ".join(cells) + " |")
    return lines


def dof_change_table(records: Sequence[Record]) -> list[str]:
    """Per category and sampler, where executed trajectories ended: never touched the object,
    or touched it with the largest DoF change (share of its range) in each of CHANGE_BINS."""
    samples = [s for s in _collected(records) if not s.get("skipped")]

    def label(lo: float, hi: float) -> str:
        return f">= {lo:.0%}" if hi == np.inf else f"{lo:.0%}-{hi:.0%}"

    bins = " | ".join(f"touched, {label(lo, hi)}" for lo, hi in CHANGE_BINS)
    lines = [f"| category | sampler | trajectories | never touched | {bins} |",
             "|---" * (4 + len(CHANGE_BINS)) + "|"]
    for category, rows in _by_category(samples):
        for sampler in [s for s in SAMPLERS if any(x["sampler"] == s for x in rows)]:
            done = [x for x in rows if x["sampler"] == sampler]
            touched = [_largest_change(x) for x in done if x["touched"]]
            shares = [sum(lo <= c < hi for c in touched) for lo, hi in CHANGE_BINS]
            cells = " | ".join(f"{100 * k / len(done):.0f} %" for k in [len(done) - len(touched), *shares])
            lines.append(f"| {category} | {sampler} | {len(done)} | {cells} |")
    return lines


def label_table(records: Sequence[Record]) -> list[str]:
    """Per split and category, the visual success label against the ground truth on the
    records' labelled trajectories: accuracy and balanced accuracy (the targets LABEL_TARGETS),
    precision and recall. A split the label was calibrated on is marked so."""
    samples = [s for r in _labelled(records) for s in r.samples if "visual_success" in s]
    lines = ["| split | category | objects | trajectories | successes | accuracy | balanced accuracy "
             "| precision | recall |", "|---" * 9 + "|"]
    for split in sorted({s["split"] for s in samples}, key=_split_order):
        title = f"{split} (calibration)" if split in CALIBRATION_SPLITS else split
        for category, rows in _by_category([s for s in samples if s["split"] == split]):
            m = label_metrics(np.array([s["visual_success"] for s in rows]), np.array([s["gt_success"] for s in rows]))
            cells = " | ".join(_metric(m[k], LABEL_TARGETS.get(k)) for k in ("accuracy", "balanced_accuracy", "precision", "recall"))
            lines.append(f"| {title} | {category} | {len({s['object_id'] for s in rows})} | {m['n']} "
                         f"| {m['positives']} | {cells} |")
    return lines


def _labelled(records: Sequence[Record]) -> Sequence[Record]:
    for r in records:
        if r.meta.get("kind") != "collection":
            raise RecordError(f"record {r.name} is not a collection")
        if not any("visual_success" in s for s in r.samples):
            raise RecordError(f"record {r.name} holds no visual labels (an unlabelled dataset)")
    return records


def _split_order(split: str) -> int:
    order = ["train", "train_seen", "val", "test_unseen_instance", "test_unseen_category"]
    return order.index(split) if split in order else len(order)


def _metric(value: float, target: float | None) -> str:
    """A rate in percent, with a mark where it misses its target."""
    if not np.isfinite(value):
        return "-"
    return f"{100 * value:.1f}" + (" (below)" if target is not None and value < target else "")


def compare_table(records: Sequence[Record]) -> list[str]:
    """ActAIM2 against Data Collection by the protocol's rules (``eval.protocol.comparison``): each
    record holding ActAIM2 samples is one seed's run; Data Collection's samples come from the same
    record, or from the records that hold no ActAIM2 samples (a baseline run once on the same
    scenes, shared by every seed)."""
    runs = [r for r in records if any(s["method"] == "actaim2" for s in r.samples)]
    if not runs:
        raise RecordError(f"none of {[r.name for r in records]} holds ActAIM2 samples")
    shared = [s for r in records if r not in runs for s in r.samples if s["method"] == "data_collection"]
    lines = comparison([r.samples + shared for r in runs], "actaim2", "data_collection",
                       COMPARE_HALVINGS, COMPARE_ROUNDS)[2:]
    return [f"**{line[3:]}**" if line.startswith("## ") else line for line in lines]  # splits: not doc headings


def errors_table(records: Sequence[Record]) -> list[str]:
    """Per validation record (``actaim2 validate``), the predictor's errors on the split's
    visually-labelled successes per keypose: translation median / 90th percentile (mm) and
    rotation median (deg), fed the selector's reconstruction of z and the true z."""
    lines = ["| record | split | keypose | keyframes | translation, reconstructed z: median / p90 (mm) "
             "| translation, true z: median / p90 (mm) | rotation median, reconstructed / true z (deg) |",
             "|---" * 7 + "|"]
    for r in records:
        if r.meta.get("kind") != "validation":
            raise RecordError(f"record {r.name} is not a validation")
        rows = {(s["eps"], s["keypose"]): s for s in r.samples}
        for keypose in dict.fromkeys(s["keypose"] for s in r.samples):
            rec, true = rows["reconstructed", keypose], rows["true", keypose]
            lines.append(f"| `{r.name}` | {r.meta['split']} | {keypose} | {rec['keyframes']} "
                         f"| {rec['translation_median_mm']:.0f} / {rec['translation_p90_mm']:.0f} "
                         f"| {true['translation_median_mm']:.0f} / {true['translation_p90_mm']:.0f} "
                         f"| {rec['rotation_median_deg']:.1f} / {true['rotation_median_deg']:.1f} |")
    return lines


def self_filter_table(records: Sequence[Record]) -> list[str]:
    """``actaim2 bench standin-self-filter``'s table: arm left and scene removed by the self-filter per placement."""
    return summary_table([s for r in records for s in r.samples])


# marker table name -> renderer of the records the marker names
TABLES: dict[str, Callable[[Sequence[Record]], list[str]]] = {
    "results": results_table,
    "runs": runs_table,
    "ssr": _evaluation(et.ssr_table),
    "mode_ssr": _evaluation(et.mode_table, grouped=True),
    "many_modes": _evaluation(et.many_modes_table, grouped=True),
    "second_mode": _evaluation(et.second_mode_table, grouped=True),
    "dependence": _evaluation(et.dependence_table, grouped=True),
    "clusters": _evaluation(et.cluster_table),
    "stops": _evaluation(et.stops_table),
    "paper": lambda records: et.paper_table(),
    "samplers": samplers_table,
    "dof_change": dof_change_table,
    "label": label_table,
    "compare": compare_table,
    "errors": errors_table,
    "self_filter": self_filter_table,
}
