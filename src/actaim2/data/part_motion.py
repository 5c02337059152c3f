"""How the object's parts moved between the robot-hidden observations O_init and O_final.

The cameras stay put and the robot is not drawn in O_init and O_final, so whatever changed
between the two depth pictures moved. From the pictures alone (no object state):

1. **Changed points.** Per camera, pixels whose depth changed by more than
   ``depth_tolerance`` are back-projected into `world`. An O_init point with no O_final point
   within ``point_tolerance`` (all cameras) and whose place some camera now sees through
   *vanished* (the part's old place); an O_final point with no O_init point near it and whose
   place some camera saw through before *appeared* (the part's new place). Surfaces that slid
   along themselves drop out, and so does background the moved part now hides in every view
   (or revealed background that no camera saw past before).
2. **Parts.** Vanished and appeared points are clustered together (DBSCAN): one cluster per
   moved part (a door and a drawer nudged in the same trajectory are two).
3. **Rigid motion per part.** A symmetric trimmed ICP finds the rigid motion T that carries
   the vanished points onto the O_final cloud and, inverted, the appeared points onto the
   O_init cloud, started from the identity, the centroid shift and the principal-axes
   alignments; the best fit wins. It gives the rotation angle and axis, and how far the part
   was carried.
4. **Part size.** The largest distance of the part's points from the rotation axis (the
   lever arm) and the changed points' extent.

An articulated part moves on a revolute or a prismatic joint, so one angle or one distance
says how far it went; whether that is 30% of its range is the labeller's question
(:mod:`actaim2.data.success`).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from actaim2.data.object_cloud import back_project
from actaim2.data.trajectory import Observation


@dataclass(frozen=True)
class MotionConfig:
    depth_tolerance: float = 0.003  # m: a pixel's depth change that counts (stored depth is in mm)
    point_tolerance: float = 0.005  # m: a point with a point of the other observation this near did not move
    carve_tolerance: float = 0.01  # m: a camera sees past a point when its depth there is this much farther
    floor_height: float = 0.005  # m: points below are the floor, which never moves
    context: float = 0.3  # m around the changed points kept for the nearest-neighbour searches
    tree_voxel: float = 0.0025  # m: the searched clouds keep one point per voxel of this size
    cluster_voxel: float = 0.01  # m: changed points in touching voxels of this size belong to one part
    pair_distance: float = 0.2  # m: a group of vanished points this near a group of appeared ones is the same part
    min_points: int = 20  # changed points a part needs (fewer: noise, specks at depth edges)
    min_part_share: float = 0.1  # smaller parts (vs the largest) are fragments: a drawer's back seen through a gap
    max_points: int = 500  # vanished and appeared points used per part (random subset, seeded)
    trim: float = 0.8  # ICP keeps this share of the closest correspondences
    iterations: int = 30  # ICP iterations per start (most converge in 5-15)
    translation_slack: float = 1.15  # a translation whose residual is within this factor of the rotation's wins
    max_angle_deg: float = 100.0  # a fit rotating more is a flipped (symmetric) solution, discarded
    min_rotation_deg: float = 5.0  # less is a translation: a hinged part pushed this little succeeds nowhere
    max_lever_ratio: float = 1.5  # a rotation about an axis farther from the part than this x its extent is a translation


@dataclass(frozen=True)
class PartMotion:
    """One moved part's rigid motion, from O_init to O_final."""

    points: int  # vanished + appeared points of the part
    angle: float  # rad, rotation of the part
    shift: float  # m, how far the centroid of the part's vanished points was carried (a drawer's travel)
    displacement: float  # m, the farthest any vanished point was carried
    radius: float  # m, largest distance of the part's points from the rotation axis; 0: the part translated
    extent: float  # m, largest side of the changed points' box along their principal axes
    residual: float  # m, mean distance of the kept correspondences after the fit
    axis: tuple[float, float, float]  # rotation axis, or the translation's direction, in `world`

    @property
    def rotated(self) -> bool:
        """A rotation (about an axis near the part, as a hinge is), not a translation."""
        return self.radius > 0.0

    def to_json(self) -> dict:
        return {k: ([round(x, 6) for x in v] if isinstance(v, tuple) else round(v, 6) if isinstance(v, float) else v)
                for k, v in asdict(self).items()}

    @classmethod
    def from_json(cls, data: dict) -> "PartMotion":
        return cls(**{k: tuple(v) if k == "axis" else v for k, v in data.items()})


def voxel_keys(points: np.ndarray, origin: np.ndarray, size: float) -> np.ndarray:
    """One int64 per voxel of side ``size`` (points at or beyond ``origin`` in every axis)."""
    ijk = np.floor((points - origin) / size).astype(np.int64)
    span = ijk.max(0) + 1 if len(ijk) else np.ones(3, np.int64)
    return (ijk[:, 0] * span[1] + ijk[:, 1]) * span[2] + ijk[:, 2]


def _world_points(observation: Observation) -> dict[str, np.ndarray]:
    out = {}
    for name, image in sorted(observation.items()):
        T = image.T_world_optical
        out[name] = back_project(image) @ T[:3, :3].T + T[:3, 3]  # NaN where no return
    return out


def seen_through(points: np.ndarray, observation: Observation, tolerance: float) -> np.ndarray:
    """Which points some camera of ``observation`` sees past: its depth at the point's pixel is
    more than ``tolerance`` beyond the point (or no return), so nothing is at the point."""
    out = np.zeros(len(points), dtype=bool)
    for image in observation.values():
        T = np.linalg.inv(image.T_world_optical)
        local = points @ T[:3, :3].T + T[:3, 3]
        z = local[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.floor(image.K[0, 0] * local[:, 0] / z + image.K[0, 2]).astype(np.int64)  # pixel centres at +0.5
            v = np.floor(image.K[1, 1] * local[:, 1] / z + image.K[1, 2]).astype(np.int64)
        h, w = image.depth.shape
        inside = (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
        depth = image.depth[v[inside], u[inside]]
        out[inside] |= (depth == 0) | (depth > z[inside] + tolerance)
    return out


def changed_points(init: Observation, final: Observation, config: MotionConfig = MotionConfig()
                   ) -> tuple[np.ndarray, np.ndarray, cKDTree | None, cKDTree | None]:
    """(vanished points, appeared points, O_init tree, O_final tree) in `world`.

    The trees hold every point of either observation within ``context`` of the changed ones
    (None when nothing changed).
    """
    if sorted(init) != sorted(final):
        raise ValueError(f"O_init cameras {sorted(init)} differ from O_final's {sorted(final)}")
    xi, xf = _world_points(init), _world_points(final)
    cand_i, cand_f, all_i, all_f = [], [], [], []
    for name in sorted(init):
        changed = np.abs(init[name].depth.ravel() - final[name].depth.ravel()) > config.depth_tolerance
        for points, cands, store in ((xi[name], cand_i, all_i), (xf[name], cand_f, all_f)):
            valid = np.isfinite(points[:, 0])
            valid[valid] = points[valid, 2] > config.floor_height
            cands.append(points[changed & valid])
            store.append(points[valid])
    ci, cf = np.concatenate(cand_i), np.concatenate(cand_f)
    if len(ci) + len(cf) == 0:
        empty = np.zeros((0, 3))
        return empty, empty, None, None
    both = np.concatenate([ci, cf])
    lo, hi = both.min(0) - config.context, both.max(0) + config.context

    def near(points: np.ndarray) -> np.ndarray:
        """The points within the context box, one per ``tree_voxel`` cell (5 cameras overlap)."""
        points = points[np.all((points >= lo) & (points <= hi), axis=1)]
        return points[np.unique(voxel_keys(points, lo, config.tree_voxel), return_index=True)[1]]

    tree_i, tree_f = cKDTree(near(np.concatenate(all_i))), cKDTree(near(np.concatenate(all_f)))
    vanished = ci[(tree_f.query(ci, distance_upper_bound=config.point_tolerance)[0] > config.point_tolerance)]
    appeared = cf[(tree_i.query(cf, distance_upper_bound=config.point_tolerance)[0] > config.point_tolerance)]
    # Hidden is not gone: keep the points whose place some camera now sees through (vanished)
    # or saw through before (appeared); background the moved part covers in every view drops out.
    vanished = vanished[seen_through(vanished, final, config.carve_tolerance)]
    appeared = appeared[seen_through(appeared, init, config.carve_tolerance)]
    return vanished, appeared, tree_i, tree_f


def _kabsch(P: np.ndarray, Q: np.ndarray, rotate: bool) -> tuple[np.ndarray, np.ndarray]:
    """R, t minimising sum |R p + t - q|^2 (R = I when not ``rotate``)."""
    cp, cq = P.mean(0), Q.mean(0)
    if not rotate:
        return np.eye(3), cq - cp
    U, _, Vt = np.linalg.svd((P - cp).T @ (Q - cq))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, cq - R @ cp


def _symmetric_icp(V: np.ndarray, A: np.ndarray, tree_i: cKDTree, tree_f: cKDTree, R: np.ndarray, t: np.ndarray,
                   rotate: bool, iterations: int, config: MotionConfig) -> tuple[np.ndarray, np.ndarray, float]:
    """Refine (R, t): V carried onto the O_final cloud, A carried back onto the O_init cloud.

    Returns the fit and its cost, the mean of the kept (closest ``trim`` share) distances.
    Neighbours are searched within ``context`` only (an unbounded search from a poor start
    costs 10x more); points without one count as that far and are trimmed first.
    """
    bound = config.context

    def match() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        dv, iv = tree_f.query(V @ R.T + t, distance_upper_bound=bound)
        da, ia = tree_i.query((A - t) @ R, distance_upper_bound=bound)  # R^T (a - t)
        return np.minimum(dv, bound), np.minimum(iv, tree_f.n - 1), np.minimum(da, bound), np.minimum(ia, tree_i.n - 1)

    def trimmed(d: np.ndarray) -> np.ndarray:
        return d <= np.quantile(d, config.trim)

    best = (np.inf, R, t)
    for _ in range(iterations + 1):
        dv, iv, da, ia = match()
        d = np.concatenate([dv, da])
        cost = float(d[trimmed(d)].mean())
        if cost > best[0] - 1e-6:  # converged (or got worse)
            break
        best = (cost, R, t)
        keep = trimmed(d) & (d < bound)
        if keep.sum() < 3:
            break
        R, t = _kabsch(np.concatenate([V, tree_i.data[ia]])[keep], np.concatenate([tree_f.data[iv], A])[keep], rotate)
    return best[1], best[2], best[0]


def _starts(V: np.ndarray, A: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Initial guesses: identity, centroid shift, and the principal axes of V turned onto A's."""
    cv, ca = V.mean(0), A.mean(0)
    starts = [(np.eye(3), np.zeros(3)), (np.eye(3), ca - cv)]
    ev = np.linalg.svd(V - cv, full_matrices=False)[2]
    ea = np.linalg.svd(A - ca, full_matrices=False)[2]
    bv = np.stack([ev[0], ev[1], np.cross(ev[0], ev[1])], axis=1)
    for s0, s1 in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        a0, a1 = s0 * ea[0], s1 * ea[1]
        R = np.stack([a0, a1, np.cross(a0, a1)], axis=1) @ bv.T
        starts.append((R, ca - R @ cv))
    return starts


def fit_rigid_motion(V: np.ndarray, A: np.ndarray, tree_i: cKDTree, tree_f: cKDTree,
                     config: MotionConfig) -> tuple[np.ndarray, np.ndarray, float] | None:
    """The part's motion (R, t, residual): the best of a translation and a rotation fit.

    Every start is refined to convergence and the closest fit kept. A translation is kept when
    it fits about as well as a rotation (``translation_slack``): a pulled drawer is a
    translation, but a free rigid fit leaves a few spurious degrees on it where the drawer
    slides into the body. Fits rotating more than ``max_angle_deg`` (a part's symmetric twin
    pose) are discarded; None if nothing is left.
    """
    fits = []
    for rotate in (True, False):
        starts = _starts(V, A) if rotate else [(np.eye(3), np.zeros(3)), (np.eye(3), A.mean(0) - V.mean(0))]
        if not rotate and fits:  # the rotation fit's shift of the part's centroid: a translation start near the truth
            R, t, _ = fits[0]
            starts.append((np.eye(3), R @ V.mean(0) + t - V.mean(0)))
        trials = []
        for R0, t0 in starts:
            R, t, cost = _symmetric_icp(V, A, tree_i, tree_f, R0, t0, rotate, config.iterations, config)
            if np.degrees(Rotation.from_matrix(R).magnitude()) <= config.max_angle_deg:
                trials.append((cost, R, t))
        if trials:
            cost, R, t = min(trials, key=lambda c: c[0])
            fits.append((R, t, cost))
    if not fits:
        return None
    rotation, translation = (fits[0], fits[1]) if len(fits) == 2 else (None, fits[0])
    if rotation is None or translation[2] <= rotation[2] * config.translation_slack:
        return translation
    return rotation


def _axis_and_radius(R: np.ndarray, t: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, float]:
    """Rotation axis of (R, t) and the largest distance of ``points`` from it (the lever arm)."""
    rotvec = Rotation.from_matrix(R).as_rotvec()
    axis = rotvec / np.linalg.norm(rotvec)
    # a point c on the axis: (I - R) c = t - (axis . t) axis (least squares; c along the axis is free)
    c = np.linalg.lstsq(np.eye(3) - R, t - (axis @ t) * axis, rcond=None)[0]
    rel = points - c
    return axis, float(np.linalg.norm(rel - np.outer(rel @ axis, axis), axis=1).max())


def _pair_one_sided_groups(points: np.ndarray, labels: np.ndarray, is_vanished: np.ndarray, distance: float) -> np.ndarray:
    """Join each group holding only vanished (or only appeared) points to a group holding the
    other kind within ``distance``: a part that moved farther than its own thickness leaves
    its old and new places apart (a drawer front pulled out of its slot). The nearest
    one-sided group of the other kind is preferred (the same part's other place), then the
    nearest mixed group."""
    labels = labels.copy()

    def kind(g: int) -> tuple[bool, bool]:
        mine = labels == g
        return bool((mine & is_vanished).any()), bool((mine & ~is_vanished).any())

    for g in range(labels.max(initial=-1) + 1):
        mine = labels == g
        has_v, has_a = kind(g)
        if has_v == has_a:  # both kinds, or merged away already
            continue
        wanted = is_vanished if has_a else ~is_vanished
        one_sided = np.isin(labels, [h for h in range(labels.max() + 1) if h != g and kind(h) == (has_a, has_v)])
        for pool in (wanted & one_sided, wanted & (labels >= 0) & (labels != g)):
            others = np.flatnonzero(pool)
            if len(others) == 0:
                continue
            d, i = cKDTree(points[others]).query(points[mine], distance_upper_bound=distance)
            if np.isfinite(d).any():
                labels[mine] = labels[others[i[np.argmin(d)]]]
                break
    return labels


def part_motions(init: Observation, final: Observation, config: MotionConfig = MotionConfig(),
                 seed: int = 0) -> list[PartMotion]:
    """The rigid motion of every moved part, largest part first (empty when nothing moved).

    Parts with fewer than ``min_part_share`` of the largest part's points are left out: they
    are bits of a moved part seen through gaps, too few and too flat for a trustworthy fit.
    """
    from sklearn.cluster import DBSCAN

    vanished, appeared, tree_i, tree_f = changed_points(init, final, config)
    if len(vanished) + len(appeared) < config.min_points:
        return []
    rng = np.random.default_rng(seed)

    def subset(points: np.ndarray, n: int) -> np.ndarray:
        return points if len(points) <= n else points[np.sort(rng.choice(len(points), n, replace=False))]

    # Parts: connected groups of changed points, found on a voxel grid (DBSCAN on the occupied
    # voxels; a dense cloud would make it quadratic), every point taking its voxel's part.
    both = np.concatenate([vanished, appeared])
    _, first, cell_of = np.unique(voxel_keys(both, both.min(0), config.cluster_voxel), return_index=True, return_inverse=True)
    cells = np.floor((both[first] - both.min(0)) / config.cluster_voxel)
    cell_labels = DBSCAN(eps=1.5, min_samples=3).fit_predict(cells)  # 18-connected voxels
    labels = cell_labels[cell_of.ravel()]
    is_vanished = np.arange(len(both)) < len(vanished)
    labels = _pair_one_sided_groups(both, labels, is_vanished, config.pair_distance)
    parts = []
    for label in range(labels.max(initial=-1) + 1):
        mine = labels == label
        if mine.sum() < config.min_points:
            continue
        v = subset(both[mine & is_vanished], config.max_points)
        a = subset(both[mine & ~is_vanished], config.max_points)
        if min(len(v), len(a)) < 4:
            continue
        best = fit_rigid_motion(v, a, tree_i, tree_f, config)
        if best is None:
            continue
        R, t, residual = best
        pts = np.concatenate([v, a])
        centred = pts - pts.mean(0)
        extent = float(np.ptp(centred @ np.linalg.svd(centred, full_matrices=False)[2].T, axis=0).max())
        angle = float(Rotation.from_matrix(R).magnitude())
        centre = v.mean(0)
        shift = R @ centre + t - centre
        axis, radius = _axis_and_radius(R, t, pts) if np.degrees(angle) >= config.min_rotation_deg else (None, np.inf)
        if radius > config.max_lever_ratio * extent:  # a translation: ICP tilts a pulled drawer by a few degrees
            axis, radius = shift / max(float(np.linalg.norm(shift)), 1e-9), 0.0
        parts.append(PartMotion(points=int(mine.sum()), angle=angle, shift=float(np.linalg.norm(shift)),
                                displacement=float(np.linalg.norm(v @ R.T + t - v, axis=1).max()), radius=radius,
                                extent=extent, residual=residual, axis=tuple(float(x) for x in axis)))
    parts.sort(key=lambda p: -p.points)
    return [p for p in parts if p.points >= config.min_part_share * parts[0].points]
