"""The tables ``actaim2 report`` writes into README.md and docs/, each from committed records.

Every table is computed by the evaluation's own code (``actaim2.eval.tables``: pooled rates with
Wilson intervals, split-half Mode SSR, the permutation test) over the records' samples; a table
naming several records pools their samples, so they must cover different (method, split) pairs.
Machine, cores and load average appear only as the records' fields (the ``runs`` table).
"""
from __future__ import annotations

from typing import Callable, Sequence

from actaim2.eval import tables as et
from actaim2.eval.evalset import SPLIT_TITLES, SPLITS
from actaim2.eval.methods import METHODS
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
        checkpoints = ", ".join(f"{c['weights_sha256'][:16]}" for c in m["checkpoints"].values())
        datasets = sorted({c["dataset_digest"] for c in m["checkpoints"].values()}
                          | ({m["dataset"]["digest"]} if "dataset" in m else set()))
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
}
