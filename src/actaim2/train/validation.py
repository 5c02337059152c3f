"""Validation figures of a trained policy on the successes of a split it never saw (issue 11, item 6).

The training curves use a 10% trajectory hold-out of ``train_seen``; these figures measure
generalisation to unseen *instances* (``train_unseen_instance`` by default), on the trajectories
the visual label calls successful (the same selection training uses: the privileged ground
truth is not consulted).

Action predictor, per keyframe with a target inside the cube, fed two embeddings:
  * ``reconstructed``: the selector's reconstruction of the trajectory's z through the posterior
    means (what the joint phase trains the predictor on, sg[eps_hat]);
  * ``true``: the standardised true z (the Goal-RVT input).
Figures, over all keyframes and per keypose phase (INIT and MANIPULATE lie off the object, so they
err differently from REACH and GRASP): translation error (median and 90th percentile, mm), rotation error (geodesic, deg, up
to the hand's half-turn symmetry about its approach axis),
gripper accuracy.

Mode selector: reconstruction error (mean squared error per dimension of eps, standardised
units, so 1.0 is predicting the mean), cluster usage of the posterior assignments
q(c | x, y, O) (how many of the K clusters receive validation trajectories) and of the prior
draws c ~ pi(O) (the clusters ``/sample_mode`` draws from).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from actaim2.data.trajectory import PHASES
from actaim2.models.predictor import ActionPredictor, decode_action, proprio_features
from actaim2.models.rotation_bins import grasp_geodesic_deg
from actaim2.models.selector_base import ModeSelector
from actaim2.models.view_geometry import CubePlacement
from actaim2.train.data import TrainingData

EMBEDDINGS = ("reconstructed", "true")


@dataclass(frozen=True)
class ActionFigures:
    keyframes: int
    translation_median_mm: float
    translation_p90_mm: float
    rotation_median_deg: float
    rotation_p90_deg: float
    gripper_accuracy: float


@torch.no_grad()
def _eps(selector: ModeSelector, init_views: torch.Tensor, z: torch.Tensor) -> dict[str, torch.Tensor]:
    """Each embedding fed to the predictor, from the keyframes' own O_init and z (already in their batch)."""
    true = selector.standardise(z)
    return {"true": true, "reconstructed": selector.reconstruct(init_views, true)}


def _figures(t: np.ndarray, r: np.ndarray, g: np.ndarray) -> ActionFigures:
    return ActionFigures(len(t), float(np.median(t)), float(np.percentile(t, 90)), float(np.median(r)),
                         float(np.percentile(r, 90)), float(g.mean()))


@torch.no_grad()
def action_figures(selector: ModeSelector, predictor: ActionPredictor, data: TrainingData, placement: CubePlacement,
                   device: torch.device, batch_size: int = 16) -> dict[str, dict[str, ActionFigures]]:
    """Errors of the predicted keyposes against the recorded ones: per embedding fed, over all
    keyframes (``"all"``) and per keypose phase (``"init"`` ... ``"manipulate"``, where it has keyframes)."""
    frames = data.keyframes()
    if len(frames) == 0:
        raise ValueError("no keyframe with a target inside the cube")
    errors: dict[str, dict[str, list[np.ndarray]]] = {k: {"t": [], "r": [], "g": []} for k in EMBEDDINGS}
    for chunk in np.array_split(frames, max(1, math.ceil(len(frames) / batch_size))):
        batch = data.keyframe_batch(chunk, device)
        proprio = proprio_features(batch["gripper"], batch["phase"])
        eps = _eps(selector, batch["init_views"], batch["z"])
        truth = batch["keypose"].cpu().numpy()
        for kind in EMBEDDINGS:
            action = decode_action(predictor(batch["views"], eps[kind], proprio), placement, predictor.config.view_index)
            errors[kind]["t"].append(1000.0 * np.linalg.norm(action.position.cpu().numpy() - truth[:, :3], axis=1))
            errors[kind]["r"].append(grasp_geodesic_deg(action.quat_xyzw.cpu().double().numpy(), truth[:, 3:7].astype(np.float64)))
            errors[kind]["g"].append(action.gripper_closed.cpu().numpy() == (truth[:, 7] > 0.5))
    out: dict[str, dict[str, ActionFigures]] = {}
    for kind, e in errors.items():
        t, r, g = (np.concatenate(e[key]) for key in ("t", "r", "g"))
        out[kind] = {"all": _figures(t, r, g)}
        for index, name in enumerate(PHASES):
            rows = frames[:, 1] == index
            if rows.any():
                out[kind][name] = _figures(t[rows], r[rows], g[rows])
    return out


@torch.no_grad()
def selector_figures(selector: ModeSelector, data: TrainingData, device: torch.device, seed: int = 0,
                     batch_size: int = 32) -> dict:
    """Reconstruction error and cluster usage (posterior assignments and prior draws)."""
    clusters = selector.config.clusters
    squared, assigned, drawn = [], [], []
    generator = torch.Generator(device=device).manual_seed(seed)
    for rows in np.array_split(np.arange(len(data)), max(1, math.ceil(len(data) / batch_size))):
        views, z = data.selector_batch(rows, device)
        true = selector.standardise(z)
        squared.append(((selector.reconstruct(views, true) - true) ** 2).mean(dim=1).cpu().numpy())
        assigned.append(selector.assign_clusters(views, true).cpu().numpy())
        drawn.append(selector.sample(views, None, generator).cluster.cpu().numpy())
    assigned_all, drawn_all = np.concatenate(assigned), np.concatenate(drawn)

    def usage(labels: np.ndarray) -> dict:
        counts = np.bincount(labels[labels >= 0], minlength=clusters) if clusters else np.zeros(0, int)
        return {"clusters_used": int((counts > 0).sum()), "counts": counts.tolist()}

    return {"trajectories": len(data), "reconstruction_mse": float(np.concatenate(squared).mean()),
            "posterior": usage(assigned_all), "prior_draws": usage(drawn_all)}


def markdown(split: str, actions: dict[str, dict[str, ActionFigures]], selector: dict) -> str:
    """The figures as the README shows them: over all keyframes, then per keypose phase."""
    lines = [f"Validation on the visually-labelled successes of `{split}` "
             f"({selector['trajectories']} trajectories, {actions['reconstructed']['all'].keyframes} keyframes):", "",
             "| eps fed to the predictor | translation median / p90 (mm) | rotation median / p90 (deg) | gripper accuracy |",
             "|---|---|---|---|"]
    names = {"reconstructed": "selector's reconstruction of z (as served after training)", "true": "true z (Goal-RVT input)"}
    for kind in EMBEDDINGS:
        a = actions[kind]["all"]
        lines.append(f"| {names[kind]} | {a.translation_median_mm:.0f} / {a.translation_p90_mm:.0f} | "
                     f"{a.rotation_median_deg:.1f} / {a.rotation_p90_deg:.1f} | {100 * a.gripper_accuracy:.1f} % |")
    lines += ["", "Per keypose (medians; reconstruction of z / true z):", "",
              "| keypose | keyframes | translation (mm) | rotation (deg) |", "|---|---|---|---|"]
    for phase in (p for p in PHASES if p in actions["true"]):
        rec, true = actions["reconstructed"][phase], actions["true"][phase]
        lines.append(f"| {phase.upper()} | {true.keyframes} | {rec.translation_median_mm:.0f} / {true.translation_median_mm:.0f} | "
                     f"{rec.rotation_median_deg:.1f} / {true.rotation_median_deg:.1f} |")
    post, prior = selector["posterior"], selector["prior_draws"]
    k = len(post["counts"])
    lines += ["", f"Selector: reconstruction MSE {selector['reconstruction_mse']:.3f} per dimension of standardised eps "
              f"(1.0 = predicting the mean); clusters receiving trajectories: {post['clusters_used']} of {k} "
              f"(posterior, counts {post['counts']}), {prior['clusters_used']} of {k} (prior draws, counts {prior['counts']})."]
    return "\n".join(lines) + "\n"
