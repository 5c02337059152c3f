"""Training and validation curves of a run, as one image (read from ``<run>/history.jsonl``).

One panel per phase: the training loss of the epoch's last batch and the loss on the held-out
10% of ``train_seen`` at each epoch end, against the phase's step; the selector panel adds the
validation reconstruction error, the predictor and joint panels the action loss's parts.
TensorBoard (``<run>/tensorboard``) has every scalar; this picture is the overview (docs/training.md).
"""
from __future__ import annotations

import json
from pathlib import Path

# phase -> (metric, label, which side); "loss" is the phase's objective
PANELS: dict[str, list[tuple[str, str, str]]] = {
    "selector": [("loss", "ELBO loss", "both"), ("reconstruction_mse", "reconstruction MSE", "val")],
    "predictor": [("action", "action loss", "both"), ("translation", "CE(p)", "val"), ("rotation", "CE(R)", "val"),
                  ("gripper", "CE(q)", "val")],
    "joint": [("loss", "L_action + L_ELBO", "both"), ("action", "action loss", "val")],
}


def read_history(run: str | Path) -> list[dict]:
    path = Path(run) / "history.jsonl"
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist: is {run} an `actaim2 train` run folder?")
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def plot_curves(history: list[dict], out: str | Path, title: str = "") -> Path:
    """Write the curves PNG; returns its path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    phases = [p for p in PANELS if any(r["phase"] == p for r in history)]
    if not phases:
        raise ValueError("the history holds no epoch of any phase")
    fig, axes = plt.subplots(1, len(phases), figsize=(5 * len(phases), 3.8), squeeze=False)
    for ax, phase in zip(axes[0], phases):
        records = [r for r in history if r["phase"] == phase]
        steps = [r["step"] for r in records]
        for metric, label, side in PANELS[phase]:
            if side == "both":
                ax.plot(steps, [r["train"].get(metric) for r in records], lw=1, alpha=0.6, label=f"{label} (train batch)")
            vals = [(s, r["val"][metric]) for s, r in zip(steps, records) if r.get("val") and metric in r["val"]]
            if vals:
                ax.plot(*zip(*vals), lw=1.8, label=f"{label} (validation)")
        ax.set_title(phase)
        ax.set_xlabel("step")
        ax.set_yscale("symlog", linthresh=1.0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
