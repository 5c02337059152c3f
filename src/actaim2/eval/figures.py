"""Pictures of an evaluation (``actaim2 evaluate --figures N``), written beside the tables.

* ``embeddings_<object>.png`` - the mode embeddings eps ActAIM2 sampled on one object, projected
  to 2-D with PCA and coloured by cluster (filled: the sample succeeded), beside the outcomes the
  samples of each cluster produced (stacked bars: each (DoF, direction) mode, and failures).
  eps is recomputed from the sample's seeds (same scene, same selector draw).
* ``heatmaps_<object>.png`` - one ActAIM2 sample re-executed: per phase (rows) and view
  (columns), the view's depth, the predictor's heatmap over it, the predicted keypose (x) and the
  position the arm reached (o).

Matplotlib (Agg, no display) and scikit-learn's PCA; both are project dependencies.
"""
from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import torch

from actaim2.eval.episode import run_sample
from actaim2.eval.sim_views import pictures
from actaim2.eval.tasks import EvalTask
from actaim2.models.predictor import proprio_features
from actaim2.perception.ortho_views import VIEWS, project


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def mode_label(mode) -> str:
    return "failure" if not mode else f"{mode[0]} {'+' if mode[1] > 0 else '-'}"


def embedding_figure(worker, tasks: list[EvalTask], records: dict[str, dict], path: Path) -> None:
    """PCA of the eps of ``tasks`` (one object's ActAIM2 samples) beside their outcomes per cluster."""
    from sklearn.decomposition import PCA

    source = worker.source("actaim2")
    eps, clusters, success, modes = [], [], [], []
    for task in tasks:
        obj = task.obj
        worker.env.reset(obj.category if not obj.folder else None, max(obj.instance, 0), seed=task.reset_seed,
                         dof_fraction=worker.setup.dof_fraction, folder=obj.folder or None)
        views = source.views("selector", pictures(worker.env, with_robot=False), worker.env)
        eps.append(source.sample_mode(views, task.cluster, task.sample_seed).eps)
        record = records[task.key]
        clusters.append(task.cluster)
        success.append(bool(record["success"]))
        modes.append(mode_label(record["mode"]))
    xy = PCA(2, random_state=0).fit_transform(np.stack(eps)) if len(eps) > 2 else np.zeros((len(eps), 2))
    plt = _pyplot()
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5))
    k = max(clusters) + 1
    colours = plt.get_cmap("tab10")(np.arange(k) % 10)
    for c in range(k):
        rows = [i for i, ci in enumerate(clusters) if ci == c]
        filled = [i for i in rows if success[i]]
        hollow = [i for i in rows if not success[i]]
        left.scatter(xy[filled, 0], xy[filled, 1], color=colours[c], label=f"cluster {c}", s=40)
        left.scatter(xy[hollow, 0], xy[hollow, 1], facecolors="none", edgecolors=colours[c], s=40)
    left.set_title(f"{tasks[0].obj.key}: sampled eps (PCA), filled = success")
    left.legend(fontsize=7, ncol=2)
    labels = sorted(set(modes), key=lambda m: (m == "failure", m))
    counts = {c: Counter(m for m, ci in zip(modes, clusters) if ci == c) for c in range(k)}
    bottom = np.zeros(k)
    for label in labels:
        values = np.array([counts[c][label] for c in range(k)], float)
        right.bar(np.arange(k), values, bottom=bottom, label=label, color="lightgrey" if label == "failure" else None)
        bottom += values
    right.set_xticks(np.arange(k))
    right.set_xlabel("cluster")
    right.set_ylabel("samples")
    right.set_title("outcomes per cluster (DoF, + opening / - closing)")
    right.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


class _TracingSource:
    """A policy source that also keeps, per phase, the views, the heatmaps and the predicted and reached positions."""

    def __init__(self, source, env):
        self.source, self.env, self.phases = source, env, []

    def begin(self, scene):
        plan = self.source.begin(scene)
        inner, model = plan.next, self.source.model

        def next_keypose(phase: int, gripper_closed: bool):
            if self.phases:
                self.phases[-1]["reached"] = self.env.tcp_pose()[:3, 3].copy()
            views = self.source.views("predictor", pictures(self.env, with_robot=True), self.env)
            keyposes = inner(phase, gripper_closed)  # the keypose, then its fallbacks (the same point)
            eps = torch.from_numpy(np.asarray(plan.eps, np.float32))[None]
            with torch.no_grad():
                proprio = proprio_features(torch.tensor([gripper_closed]), torch.tensor([phase]))
                out = model.predictor(torch.from_numpy(views.data)[None].to(model.device), eps.to(model.device), proprio.to(model.device))
            heat = torch.softmax(out.heatmaps[0].flatten(1).float(), -1).reshape(out.heatmaps.shape[1:]).cpu().numpy()
            self.phases.append({"views": views.data, "heatmaps": heat, "predicted": np.asarray(keyposes[0].position), "reached": None})
            return keyposes

        plan.next = next_keypose
        return plan


def heatmap_figure(worker, task: EvalTask, path: Path) -> dict:
    """Re-execute ``task`` (an ActAIM2 sample) and draw its per-view heatmaps; returns the record of the re-run."""
    tracing = _TracingSource(worker.source(task.method), worker.env)
    record = run_sample(worker.env, worker.planner, worker.executor, worker.cloud_config, tracing, task,
                        worker.setup.dof_fraction, worker.setup.velocity_scaling)
    if tracing.phases:
        tracing.phases[-1]["reached"] = worker.env.tcp_pose()[:3, 3].copy()
    config = tracing.source.makers["predictor"].perception.config
    depth = config.channels.index("depth") if "depth" in config.channels else None
    plt = _pyplot()
    rows = max(1, len(tracing.phases))
    fig, axes = plt.subplots(rows, len(VIEWS), figsize=(2.2 * len(VIEWS), 2.2 * rows), squeeze=False)
    for i, phase in enumerate(tracing.phases):
        points = [phase["predicted"]] + ([phase["reached"]] if i < record["phases_executed"] else [])
        u, v, _ = project(np.stack(points), config.center, config.half_extent, config.resolution)
        for j, name in enumerate(VIEWS):
            ax = axes[i, j]
            if depth is not None:
                ax.imshow(phase["views"][j, depth], cmap="gray")
            ax.imshow(phase["heatmaps"][j], cmap="magma", alpha=0.6)
            ax.scatter(u[j, :1], v[j, :1], marker="x", color="cyan", s=40)
            ax.scatter(u[j, 1:], v[j, 1:], facecolors="none", edgecolors="lime", s=40)
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                ax.set_title(name, fontsize=8)
            if j == 0:
                ax.set_ylabel(["INIT", "REACH", "GRASP", "MANIPULATE"][i], fontsize=8)
    fig.suptitle(f"{task.obj.key} cluster {task.cluster}: heatmap, predicted (x), reached (o); "
                 f"{'success' if record['success'] else 'failure'} ({record['largest_change']:.2f} of the range)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return record


def write_figures(worker, tasks: list[EvalTask], records: dict[str, dict], out: Path, objects: int) -> list[Path]:
    """Both figures for the first ``objects`` objects with ActAIM2 results; the paths written."""
    out.mkdir(parents=True, exist_ok=True)
    by_object: dict[str, list[EvalTask]] = {}
    for t in tasks:
        if t.method == "actaim2" and t.key in records:
            by_object.setdefault(t.obj.key, []).append(t)
    written = []
    for key, object_tasks in list(by_object.items())[:objects]:
        name = key.replace(":", "_").replace("/", "_")
        embedding_figure(worker, object_tasks, records, out / f"embeddings_{name}.png")
        chosen = next((t for t in object_tasks if records[t.key]["success"]), object_tasks[0])
        heatmap_figure(worker, chosen, out / f"heatmaps_{name}.png")
        written += [out / f"embeddings_{name}.png", out / f"heatmaps_{name}.png"]
    return written
