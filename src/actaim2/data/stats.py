"""Dataset statistics as markdown tables: success per category and sampler, outcome diversity, size, speed.

Success is shown twice: the visual label (what training uses) and the ground-truth criterion
(privileged; some DoF moved by more than 30% of its range). Diversity counts the *outcomes*
of ground-truth-successful trajectories: which DoF moved most, and in which direction; a sampler
that only ever closes the same door finds one outcome, one that also opens it and pulls the
drawer finds three. The normalised entropy of the outcome histogram (1 = all outcomes equally
often) shows how evenly they are covered.
"""
from __future__ import annotations

import json
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from actaim2.sim.success import SUCCESS_FRACTION

RUNS_FILE = "runs.jsonl"  # one line per `actaim2 collect` stage run: trajectories, wall time, workers (and --ray)


def outcome(entry: dict) -> str | None:
    """'dof<k>+' / 'dof<k>-' for the DoF that moved most (beyond the criterion), else None."""
    change = np.asarray(entry["dof_change"], float)
    if change.size == 0 or np.abs(change).max() <= SUCCESS_FRACTION:
        return None
    k = int(np.argmax(np.abs(change)))
    return f"dof{k}{'+' if change[k] > 0 else '-'}"


def _percent(value: float) -> str:
    return "-" if np.isnan(value) else f"{100 * value:.1f}%"


def _rate(values: list[bool]) -> str:
    return f"{100.0 * np.mean(values):.1f}% ({sum(values)}/{len(values)})" if values else "-"


def success_table(entries: list[dict]) -> str:
    samplers = sorted({e["sampler"] for e in entries})
    categories = sorted({e["category"] for e in entries})
    labelled = all("label" in e for e in entries)
    head = "| category | " + " | ".join(f"{s} (gt)" + (f" | {s} (visual)" if labelled else "") for s in samplers) + " |"
    lines = [head, "|" + "---|" * (1 + len(samplers) * (2 if labelled else 1))]
    for cat in categories + ["all"]:
        cells = []
        for s in samplers:
            sel = [e for e in entries if e["sampler"] == s and (cat == "all" or e["category"] == cat)]
            cells.append(_rate([e["gt_success"] for e in sel]))
            if labelled:
                cells.append(_rate([e["label"] for e in sel]))
        lines.append(f"| {cat} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def diversity_table(entries: list[dict]) -> str:
    lines = ["| category | sampler | successes | distinct outcomes | normalised entropy | outcomes |", "|---|---|---|---|---|---|"]
    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for e in entries:
        groups[(e["category"], e["sampler"])].append(e)
        groups[(e["category"], "all")].append(e)
    for (cat, sampler), sel in sorted(groups.items()):
        counts = Counter(o for o in map(outcome, sel) if o is not None)
        n = sum(counts.values())
        p = np.array(list(counts.values()), float) / max(n, 1)
        entropy = float(-(p * np.log(p)).sum() / np.log(len(p))) if len(p) > 1 else 0.0
        summary = ", ".join(f"{k}: {v}" for k, v in sorted(counts.items()))
        lines.append(f"| {cat} | {sampler} | {n} | {len(counts)} | {entropy:.2f} | {summary or '-'} |")
    return "\n".join(lines)


def size_table(entries: list[dict]) -> str:
    sizes = np.array([e["size"] for e in entries], float)
    return "\n".join([
        "| trajectories | mean bytes / trajectory | max bytes / trajectory | total |",
        "|---|---|---|---|",
        f"| {len(sizes)} | {sizes.mean() / 1e6:.2f} MB | {sizes.max() / 1e6:.2f} MB | {sizes.sum() / 1e9:.2f} GB |",
    ])


def throughput_table(root: Path) -> str:
    path = Path(root) / RUNS_FILE
    runs = [json.loads(line) for line in path.read_text().splitlines() if line.strip()] if path.exists() else []
    lines = ["| run | workers | trajectories | wall time | trajectories / s |", "|---|---|---|---|---|"]
    for i, r in enumerate(runs):
        rate = r["trajectories"] / r["seconds"] if r["seconds"] > 0 else float("nan")
        lines.append(f"| {i} ({r['stage']}) | {r['workers']} | {r['trajectories']} | {r['seconds']:.0f} s | {rate:.2f} |")
    return "\n".join(lines)


def labelling_table(report: dict) -> str:
    """The visual label's accuracy per split and per category, and the measured alternatives."""
    if "method" not in report:  # labelling.json of the per-object score this version replaced
        return "labelled by an earlier version (per-object score): run the same `actaim2 collect` again to relabel"
    metrics = ("accuracy", "balanced_accuracy", "precision", "recall")
    reach = f"; moved parts with a known reach: {_percent(report['parts_with_known_reach'])}" if "parts_with_known_reach" in report else ""
    lines = [f"label: {report['method']}; calibrated on split '{report['calibration_split']}'{reach}", "",
             "| split | trajectories | successes (gt) | accuracy | balanced accuracy | precision | recall | false pos. | false neg. |",
             "|---|---|---|---|---|---|---|---|---|"]
    rows = dict(report["per_split"])
    if report.get("other_splits"):
        rows["all but calibration"] = report["other_splits"]
    for split, m in rows.items():
        cells = " | ".join(_percent(m[k]) for k in metrics)
        lines.append(f"| {split} | {m['n']} | {m['positives']} | {cells} | {m['false_positives']} | {m['false_negatives']} |")
    lines += ["", "| category | split | trajectories | successes (gt) | accuracy | false pos. | false neg. |", "|---|---|---|---|---|---|---|"]
    for category, m in report["per_category"].items():
        lines.append(f"| {category} | {m['split']} | {m['n']} | {m['positives']} | {_percent(m['accuracy'])} | "
                     f"{m['false_positives']} | {m['false_negatives']} |")
    lines += ["", "Alternatives (measured on the same trajectories; thresholds calibrated on the same split):", "",
              "| score | split | accuracy | balanced accuracy | precision | recall |", "|---|---|---|---|---|---|"]
    for name, alt in [("used: " + report["method"].split(" (")[0] + " + model", report), *report["alternatives"].items()]:
        parts = dict(alt["per_split"])
        if alt.get("other_splits"):
            parts["all but calibration"] = alt["other_splits"]
        for split, m in parts.items():
            lines.append(f"| {name} | {split} | " + " | ".join(_percent(m[k]) for k in metrics) + " |")
    return "\n".join(lines)
