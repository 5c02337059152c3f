"""Validation figures of a trained policy on the successes of a split it never saw.

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

Outcome following (the Mode SSR's offline cause): a trajectory's outcome is the (DoF, direction)
it moved most (its index entry's ``dof_change``, a fraction of each DoF's range, as the evaluation
measures). Fed a keyframe's own true eps, does the predicted point lie nearest a demonstrated
target (same object, same keypose, another trajectory) of that trajectory's outcome? Against
always guessing the object's most frequent outcome among those other trajectories. Only objects
whose other trajectories show two or more outcomes count. If the predictor places keyposes by
the scene alone, the first rate is no better than the second, and no cluster can select a mode.
The same rate for the demonstrated point itself is the most a predictor can score: different
outcomes often start at the same handle, so it is highest at MANIPULATE.

Outcome following as served (``drawn_following``): at REACH and MANIPULATE (where to act, which way
to move), each keyframe is fed one eps drawn from each cluster on its trajectory's O_init instead of
its own true eps. Each draw names an outcome (its nearest true eps's, as below); does the predicted
point's nearest other demonstration have it? Against the same with the names shuffled among the
keyframe's draws, and with the number of distinct outcomes the K points reach. Why: fed true eps the
predictor may follow outcomes that the selector's draws, lying closer together, never reach.

Outcome following with another outcome's eps (``swapped_following``): at the same phases, each
keyframe is fed, on its own views, the true eps of a trajectory of the same object with another
outcome (its partner, drawn at random). How far does the point move, and does its nearest other
demonstration now have the partner's outcome more often, and its own less? Why: it tells a predictor
that reads eps but is served draws too alike to move it from one that places keyposes by the views
alone (a point that does not move; both rates unchanged).

The links before it, on the same objects (``mode_chain_figures``): does eps name the outcome at
all (the outcome of each trajectory's nearest other true eps, leave-one-out, against the
majority), and do the clusters select outcomes (eps drawn from each cluster, draw j on the O_init of the
object's j-th trajectory as every evaluation sample has its own reset), labelled by the outcome of its nearest true eps; mutual information of cluster and
label with the evaluation's permutation test, ``actaim2.metrics.mode_dependence``)? And how much of
the evaluation's 2nd-mode SSR do the clusters allow: the Mode SSR (``actaim2.metrics.mode_ssr``, its
split-half choice) of those labels, as if every drawn eps were executed with success and reached
its label's outcome, beside the same with the labels shuffled among the object's draws. With the
evaluation's 4 draws per cluster it is the 2nd-mode figure a perfect predictor would score there.

Mode selector: reconstruction error (mean squared error per dimension of eps, standardised
units, so 1.0 is predicting the mean), cluster usage of the posterior assignments
q(c | x, y, O) (how many of the K clusters receive validation trajectories) and of the prior
draws c ~ pi(O) (the clusters ``/sample_mode`` draws from).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np
import torch

from actaim2.data.trajectory import PHASES
from actaim2.metrics.mode_dependence import Dependence, dependence
from actaim2.metrics.mode_ssr import GroupSample, ModeResult, object_mode_ssr, pooled
from actaim2.metrics.stats import Rate
from actaim2.models.predictor import ActionPredictor, decode_action, proprio_features
from actaim2.models.rotation_bins import grasp_geodesic_deg
from actaim2.models.selector_base import ModeSelector
from actaim2.models.view_geometry import CubePlacement
from actaim2.train.data import TrainingData
from actaim2.train.served_eps import nearest_true

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


@dataclass(frozen=True)
class KeyframePredictions:
    """The predictor's keyposes for every keyframe of the data, per embedding fed (``EMBEDDINGS``)."""

    frames: np.ndarray  # (K, 2) [trajectory, phase]
    truth: np.ndarray  # (K, 8) the recorded keyposes
    position: dict[str, np.ndarray]  # (K, 3) world metres
    quat_xyzw: dict[str, np.ndarray]  # (K, 4)
    gripper_closed: dict[str, np.ndarray]  # (K,) bool


@torch.no_grad()
def predict_keyframes(selector: ModeSelector, predictor: ActionPredictor, data: TrainingData, placement: CubePlacement,
                      device: torch.device, batch_size: int = 16) -> KeyframePredictions:
    """One pass of the predictor over the keyframes per embedding; every figure below reads it."""
    frames = data.keyframes()
    if len(frames) == 0:
        raise ValueError("no keyframe with a target inside the cube")
    truth: list[np.ndarray] = []
    decoded: dict[str, list] = {k: [] for k in EMBEDDINGS}
    for chunk in np.array_split(frames, max(1, math.ceil(len(frames) / batch_size))):
        batch = data.keyframe_batch(chunk, device)
        proprio = proprio_features(batch["gripper"], batch["phase"])
        eps = _eps(selector, batch["init_views"], batch["z"])
        truth.append(batch["keypose"].cpu().numpy())
        for kind in EMBEDDINGS:
            decoded[kind].append(decode_action(predictor(batch["views"], eps[kind], proprio), placement,
                                              predictor.config.view_index, predictor.config.decode_sigma_px))

    def join(kind: str, field: str) -> np.ndarray:
        return np.concatenate([getattr(a, field).cpu().numpy() for a in decoded[kind]])

    return KeyframePredictions(frames, np.concatenate(truth), {k: join(k, "position") for k in EMBEDDINGS},
                               {k: join(k, "quat_xyzw") for k in EMBEDDINGS}, {k: join(k, "gripper_closed") for k in EMBEDDINGS})


def action_figures(predictions: KeyframePredictions) -> dict[str, dict[str, ActionFigures]]:
    """Errors of the predicted keyposes against the recorded ones: per embedding fed, over all
    keyframes (``"all"``) and per keypose phase (``"init"`` ... ``"manipulate"``, where it has keyframes)."""
    truth, phase = predictions.truth, predictions.frames[:, 1]
    out: dict[str, dict[str, ActionFigures]] = {}
    for kind in EMBEDDINGS:
        t = 1000.0 * np.linalg.norm(predictions.position[kind] - truth[:, :3], axis=1)
        r = grasp_geodesic_deg(predictions.quat_xyzw[kind].astype(np.float64), truth[:, 3:7].astype(np.float64))
        g = predictions.gripper_closed[kind] == (truth[:, 7] > 0.5)
        out[kind] = {"all": _figures(t, r, g)}
        for index, name in enumerate(PHASES):
            rows = phase == index
            if rows.any():
                out[kind][name] = _figures(t[rows], r[rows], g[rows])
    return out


@dataclass(frozen=True)
class OutcomeFigures:
    keyframes: int
    nearest_demo_same_outcome: float  # predicted point's nearest other demonstration has the keyframe's outcome
    majority_outcome: float  # the object's most frequent other outcome is the keyframe's
    demonstrated_point: float  # the first rate for the demonstrated point itself: what a perfect predictor scores


def outcome_figures(predictions: KeyframePredictions, objects: Sequence[str],
                    outcomes: Sequence[str]) -> dict[str, OutcomeFigures]:
    """Per keypose phase: does the point predicted from the true eps follow the trajectory's outcome?
    ``objects`` and ``outcomes`` are per trajectory of the predicted data (module docstring)."""
    return outcome_rates(predictions.position["true"], predictions.truth[:, :3], predictions.frames,
                         np.asarray(objects), np.asarray(outcomes))


@dataclass(frozen=True)
class DrawnFollowing:
    keyframes: int
    follows_named_outcome: float  # the predicted point's nearest other demonstration has the draw's named outcome
    shuffled: float  # the same with the names shuffled among the keyframe's draws: no following
    distinct_outcomes: float  # distinct outcomes the K clusters' points reach, per keyframe


DRAWN_FOLLOWING_PHASES = ("reach", "manipulate")


@torch.no_grad()
def drawn_following(selector: ModeSelector, predictor: ActionPredictor, data: TrainingData, placement: CubePlacement,
                    predictions: KeyframePredictions, objects: Sequence[str], outcomes: Sequence[str],
                    device: torch.device, seed: int = 0, noise_scale: float = 1.0) -> dict[str, DrawnFollowing]:
    """Per phase of ``DRAWN_FOLLOWING_PHASES``: does the point follow the outcome of eps drawn as served (module
    docstring; at ``noise_scale``, ``ModeSelector.sample``'s)? Empty for a selector without clusters.
    ``predictions`` gives the demonstrated targets."""
    if selector.config.kind == "cvae":
        return {}
    objects, outcomes = np.asarray(objects), np.asarray(outcomes)
    frames, target = predictions.frames, predictions.truth[:, :3]
    trajectory = frames[:, 0]
    k = selector.config.clusters
    generator = torch.Generator(device=device).manual_seed(seed)
    shuffle = np.random.default_rng(seed)
    true = selector.standardise(torch.from_numpy(np.asarray(data.z)).to(device))
    result: dict[str, DrawnFollowing] = {}
    for name in DRAWN_FOLLOWING_PHASES:
        hits, shuffled, distinct = [], [], []
        for row, others in _scored_rows(frames, objects, outcomes, PHASES.index(name)):
            rows = np.flatnonzero(objects == objects[trajectory[row]])
            batch = data.keyframe_batch(frames[row : row + 1], device)
            drawn = torch.cat([selector.sample(batch["init_views"], c, generator, noise_scale).eps for c in range(k)])
            named = outcomes[rows[nearest_true(drawn, true[rows])]]
            views = batch["views"].expand(k, *batch["views"].shape[1:])
            out = predictor(views, drawn, proprio_features(batch["gripper"], batch["phase"]).expand(k, -1))
            points = decode_action(out, placement, predictor.config.view_index, predictor.config.decode_sigma_px).position
            reached = np.array([_nearest_outcome(q, target[others], outcomes[trajectory[others]])
                                for q in points.cpu().numpy()])
            hits += list(reached == named)
            shuffled += list(reached == shuffle.permutation(named))
            distinct.append(len(set(reached)))
        if distinct:
            result[name] = DrawnFollowing(len(distinct), float(np.mean(hits)), float(np.mean(shuffled)), float(np.mean(distinct)))
    return result


@dataclass(frozen=True)
class SwappedFollowing:
    keyframes: int
    moved_median_mm: float  # how far the point moves when fed the partner's eps instead of its own
    partner_outcome_own_eps: float  # the point's nearest other demonstration has the partner's outcome, own eps fed
    partner_outcome_swapped: float  # the same, the partner's eps fed
    own_outcome_own_eps: float  # ... has the keyframe's own outcome, own eps fed
    own_outcome_swapped: float  # the same, the partner's eps fed


@torch.no_grad()
def swapped_following(selector: ModeSelector, predictor: ActionPredictor, data: TrainingData, placement: CubePlacement,
                      predictions: KeyframePredictions, objects: Sequence[str], outcomes: Sequence[str],
                      device: torch.device, seed: int = 0, batch_size: int = 16) -> dict[str, SwappedFollowing]:
    """Per phase of ``DRAWN_FOLLOWING_PHASES``: fed another outcome's true eps on its own views, where does
    each keyframe's point go (module docstring)? ``predictions`` gives the points fed the own true eps."""
    objects, outcomes = np.asarray(objects), np.asarray(outcomes)
    frames, trajectory = predictions.frames, predictions.frames[:, 0]
    rng = np.random.default_rng(seed)
    partner = np.full(len(frames), -1)
    for name in DRAWN_FOLLOWING_PHASES:
        for row, _ in _scored_rows(frames, objects, outcomes, PHASES.index(name)):
            t = trajectory[row]
            partner[row] = rng.choice(np.flatnonzero((objects == objects[t]) & (outcomes != outcomes[t])))
    swapped = np.full((len(frames), 3), np.nan)
    rows = np.flatnonzero(partner >= 0)
    true = selector.standardise(torch.from_numpy(np.asarray(data.z)).to(device))
    for start in range(0, len(rows), batch_size):
        chunk = rows[start : start + batch_size]
        batch = data.keyframe_batch(frames[chunk], device)
        out = predictor(batch["views"], true[partner[chunk]], proprio_features(batch["gripper"], batch["phase"]))
        swapped[chunk] = decode_action(out, placement, predictor.config.view_index,
                                       predictor.config.decode_sigma_px).position.cpu().numpy()
    return swap_rates(predictions.position["true"], swapped, predictions.truth[:, :3], frames, objects, outcomes, partner)


def swap_rates(own: np.ndarray, swapped: np.ndarray, target: np.ndarray, frames: np.ndarray, objects: np.ndarray,
               outcomes: np.ndarray, partner: np.ndarray) -> dict[str, SwappedFollowing]:
    """The figures from the points (K, 3) predicted with the own and the partner's eps; ``partner`` (K,) is the
    partner trajectory of each keyframe, -1 where none was fed (those rows are not scored)."""
    outcome = outcomes[frames[:, 0]]
    result: dict[str, SwappedFollowing] = {}
    for index, name in enumerate(PHASES):
        scored = [(row, others) for row, others in _scored_rows(frames, objects, outcomes, index) if partner[row] >= 0]
        if not scored:
            continue
        moved, rates = [], []
        for row, others in scored:
            reached = [_nearest_outcome(at, target[others], outcome[others]) for at in (own[row], swapped[row])]
            rates.append([reached[0] == outcomes[partner[row]], reached[1] == outcomes[partner[row]],
                          reached[0] == outcome[row], reached[1] == outcome[row]])
            moved.append(1000.0 * np.linalg.norm(swapped[row] - own[row]))
        result[name] = SwappedFollowing(len(scored), float(np.median(moved)), *map(float, np.mean(rates, axis=0)))
    return result


def _nearest_outcome(point: np.ndarray, targets: np.ndarray, outcomes: np.ndarray) -> str:
    """The outcome of the demonstration whose point (of ``targets``) lies nearest ``point``."""
    return outcomes[np.argmin(np.linalg.norm(targets - point, axis=1))]


def _is_most_frequent(outcome: str, others: np.ndarray) -> bool:
    """Would guessing the most frequent of ``others`` (ties: the first by name) give ``outcome``?"""
    values, counts = np.unique(others, return_counts=True)
    return bool(values[np.argmax(counts)] == outcome)


def _scored_rows(frames: np.ndarray, objects: np.ndarray, outcomes: np.ndarray,
                 index: int) -> Iterator[tuple[int, np.ndarray]]:
    """(row, others) for each keyframe of phase ``index`` whose other demonstrations (same object and
    keypose, other trajectories; ``others`` their rows) show two or more outcomes: the keyframes an
    outcome-following figure can score. ``objects`` and ``outcomes`` are per trajectory."""
    trajectory, phase = frames[:, 0], frames[:, 1]
    obj = objects[trajectory]
    for row in np.flatnonzero(phase == index):
        others = np.flatnonzero((phase == index) & (obj == obj[row]) & (trajectory != trajectory[row]))
        if len(set(outcomes[trajectory[others]])) >= 2:
            yield row, others


def outcome_rates(point: np.ndarray, target: np.ndarray, frames: np.ndarray, objects: np.ndarray,
                  outcomes: np.ndarray) -> dict[str, OutcomeFigures]:
    """The figures from predicted and demonstrated points (K, 3) of keyframes (K, 2) [trajectory, phase]."""
    outcome = outcomes[frames[:, 0]]
    result: dict[str, OutcomeFigures] = {}
    for index, name in enumerate(PHASES):
        hits, majority, ceiling = [], [], []
        for row, others in _scored_rows(frames, objects, outcomes, index):
            for scores, at in ((hits, point[row]), (ceiling, target[row])):
                scores.append(_nearest_outcome(at, target[others], outcome[others]) == outcome[row])
            majority.append(_is_most_frequent(outcome[row], outcome[others]))
        if hits:
            result[name] = OutcomeFigures(len(hits), float(np.mean(hits)), float(np.mean(majority)), float(np.mean(ceiling)))
    return result


@dataclass(frozen=True)
class ModeChainFigures:
    trajectories: int  # of the objects whose trajectories show two or more outcomes
    eps_nearest_same_outcome: float  # the nearest other true eps (same object) has the trajectory's outcome
    majority_outcome: float  # the object's most frequent other outcome is the trajectory's
    clusters: Dependence | None  # cluster against the outcome its drawn eps lie nearest (None: no clusters)
    second_mode_ceiling: Rate | None  # 2nd-mode SSR of the drawn eps' labels (None: no clusters)
    second_mode_shuffled: Rate | None  # the same with the labels shuffled among the object's draws
    true_spread: float  # mean distance between two true eps of one object (nan: no clusters)
    drawn_spread: float  # mean distance between two of its drawn eps (all clusters' draws together)


@torch.no_grad()
def mode_chain_figures(selector: ModeSelector, data: TrainingData, objects: Sequence[str], outcomes: Sequence[str],
                       device: torch.device, draws: int = 4, seed: int = 0, noise_scale: float = 1.0) -> ModeChainFigures:
    """Does eps name the outcome, and do the selector's clusters select it (module docstring; draws at
    ``noise_scale``)?"""
    objects, outcomes = np.asarray(objects), np.asarray(outcomes)
    generator = torch.Generator(device=device).manual_seed(seed)
    with_clusters = selector.config.kind != "cvae"
    hits, majority, per_object, ceiling, shuffled, spread = [], [], [], [], [], []
    shuffle = np.random.default_rng(seed)
    for obj in np.unique(objects):
        rows = np.flatnonzero(objects == obj)
        if len(set(outcomes[rows])) < 2:
            continue
        views, z = data.selector_batch(rows, device)
        true = selector.standardise(z)
        distance = torch.cdist(true, true).cpu().numpy()
        np.fill_diagonal(distance, np.inf)
        for i, row in enumerate(rows):
            hits.append(outcomes[rows[np.argmin(distance[i])]] == outcomes[row])
            majority.append(_is_most_frequent(outcomes[row], outcomes[np.delete(rows, i)]))
        if with_clusters:
            condition = views[placement_rows(len(rows), draws)]
            groups, labels, drawn_all = [], [], []
            for cluster in range(selector.config.clusters):
                drawn = selector.sample(condition, cluster, generator, noise_scale).eps
                labels += list(outcomes[rows[nearest_true(drawn, true)]])
                groups += [cluster] * draws
                drawn_all.append(drawn)
            spread.append((torch.pdist(true).mean().item(), torch.pdist(torch.cat(drawn_all)).mean().item()))
            per_object.append((np.asarray(groups), np.unique(labels, return_inverse=True)[1]))
            ceiling.append(label_mode_ssr(groups, labels, draws, str(obj)))
            shuffled.append(label_mode_ssr(groups, list(shuffle.permutation(labels)), draws, str(obj)))
    scored = with_clusters and bool(per_object)
    return ModeChainFigures(len(hits), float(np.mean(hits)) if hits else float("nan"),
                            float(np.mean(majority)) if majority else float("nan"),
                            dependence(per_object) if scored else None,
                            pooled(ceiling, 2) if scored else None, pooled(shuffled, 2) if scored else None,
                            *(np.mean(spread, axis=0).tolist() if scored else (float("nan"), float("nan"))))


def placement_rows(trajectories: int, draws: int) -> np.ndarray:
    """Which of an object's trajectories lends its O_init to each of a cluster's ``draws`` draws: one after
    another, round again when the object has fewer. The evaluation draws every sample on its own reset, so
    a cluster that names one outcome on one placement and another on the next scores as it would there."""
    return np.arange(draws) % trajectories


def label_mode_ssr(groups: Sequence[int], labels: Sequence[str], draws: int, obj: str) -> list[ModeResult]:
    """Modes 1 and 2 of one object's drawn eps, each labelled with an outcome ("1-": DoF 1, down)."""
    samples = [GroupSample(int(g), i % draws, (label[:-1], 1 if label[-1] == "+" else -1))
               for i, (g, label) in enumerate(zip(groups, labels))]
    return object_mode_ssr(samples, 2, obj)


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


def markdown(split: str, actions: dict[str, dict[str, ActionFigures]], selector: dict,
             outcomes: dict[str, OutcomeFigures], chain: ModeChainFigures, drawn: dict[str, DrawnFollowing],
             swapped: dict[str, SwappedFollowing], noise_scale: float = 1.0) -> str:
    """The figures as validation.md shows them: over all keyframes, then per keypose phase (draws at ``noise_scale``)."""
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
    if chain.trajectories:
        clusters = chain.clusters.cell() if chain.clusters else "no clusters"
        lines += ["", f"Mode chain ({chain.trajectories} trajectories of objects showing two or more outcomes): the nearest "
                  f"other true eps has the trajectory's outcome {100 * chain.eps_nearest_same_outcome:.1f} % (most frequent "
                  f"other outcome: {100 * chain.majority_outcome:.1f} %); cluster against the outcome of its drawn eps' "
                  f"nearest true eps, MI {clusters}."]
        if chain.second_mode_ceiling is not None:
            lines += ["", f"2nd-mode SSR the clusters allow (those labels as outcomes, every draw a success; "
                      f"the evaluation's split-half choice): {chain.second_mode_ceiling.cell()} % "
                      f"({chain.second_mode_ceiling.trials} half-B draws), labels shuffled among the object's draws "
                      f"{chain.second_mode_shuffled.cell()} %. Two eps of one object lie {chain.true_spread:.2f} apart "
                      f"on average when true, {chain.drawn_spread:.2f} when drawn (standardised eps; noise scale {noise_scale:g})."]
    else:
        lines += ["", "Mode chain and outcome following: no object's trajectories show two or more outcomes."]
    lines += ["", "Outcome following (true z; objects whose other trajectories show two or more outcomes): the "
              "nearest other demonstration has the trajectory's outcome, from the predicted point and from the "
              "demonstrated one (the most a predictor can score); the object's most frequent other outcome is the trajectory's:", "",
              "| keypose | keyframes | predicted point | demonstrated point | most frequent outcome |", "|---|---|---|---|---|"]
    for phase, f in outcomes.items():
        lines.append(f"| {phase.upper()} | {f.keyframes} | {100 * f.nearest_demo_same_outcome:.1f} % | "
                     f"{100 * f.demonstrated_point:.1f} % | {100 * f.majority_outcome:.1f} % |")
    if drawn:
        lines += ["", f"Outcome following as served (one eps drawn from each cluster on the trajectory's O_init at noise "
                  f"scale {noise_scale:g}; each names "
                  "the outcome of its nearest true eps): the predicted point's nearest other demonstration has the named "
                  "outcome, against the names shuffled among the keyframe's draws:", "",
                  "| keypose | keyframes | follows the named outcome | names shuffled | distinct outcomes reached per keyframe |",
                  "|---|---|---|---|---|"]
        for phase, f in drawn.items():
            lines.append(f"| {phase.upper()} | {f.keyframes} | {100 * f.follows_named_outcome:.1f} % | "
                         f"{100 * f.shuffled:.1f} % | {f.distinct_outcomes:.2f} of {len(selector['posterior']['counts'])} draws |")
    if swapped:
        lines += ["", "Outcome following with another outcome's eps (fed, on the keyframe's own views, the true eps of a "
                  "trajectory of the same object with another outcome, its partner): how far the point moves, and "
                  "whose outcome its nearest other demonstration has:", "",
                  "| keypose | keyframes | point moved, median (mm) | partner's outcome, own eps / partner's eps | "
                  "own outcome, own eps / partner's eps |", "|---|---|---|---|---|"]
        for phase, f in swapped.items():
            lines.append(f"| {phase.upper()} | {f.keyframes} | {f.moved_median_mm:.0f} | "
                         f"{100 * f.partner_outcome_own_eps:.1f} / {100 * f.partner_outcome_swapped:.1f} % | "
                         f"{100 * f.own_outcome_own_eps:.1f} / {100 * f.own_outcome_swapped:.1f} % |")
    post, prior = selector["posterior"], selector["prior_draws"]
    k = len(post["counts"])
    lines += ["", f"Selector: reconstruction MSE {selector['reconstruction_mse']:.3f} per dimension of standardised eps "
              f"(1.0 = predicting the mean); clusters receiving trajectories: {post['clusters_used']} of {k} "
              f"(posterior, counts {post['counts']}), {prior['clusters_used']} of {k} (prior draws, counts {prior['counts']})."]
    return "\n".join(lines) + "\n"
