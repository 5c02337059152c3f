"""Gripper rotation <-> 72 bins per Euler angle, the predictor's rotation classes (RVT's scheme).

Conventions, stated because the authors' code got them wrong (it read (w, x, y, z) quaternions
as (x, y, z, w)):

* Quaternions are (x, y, z, w), as everywhere in this library (:mod:`actaim2.geometry`).
  q and -q are the same rotation and give the same bins: encoding goes through the rotation.
* Euler angles are SciPy's extrinsic ``"xyz"`` (as RVT): R = Rz(gamma) @ Ry(beta) @ Rx(alpha),
  each angle in [-180, 180) degrees, bin k covering [-180 + 5k, -180 + 5(k+1)) and decoding
  to its centre. Encoded bins have beta in [-90, 90] (the other Euler solution is mirrored
  onto it), so each rotation has one bin triple. Decoded quaternions have w >= 0.

Error bound. Rounding each angle to its bin centre errs by <= 2.5 deg per angle, which bounds the
geodesic error by sqrt(3) * 2.5 = 4.33 deg only where the three rotation axes are orthogonal
(beta = 0). To first order the error is |w|^2 = da^2 + db^2 + dg^2 - 2 sin(beta) da dg: the
roll and yaw axes align as beta nears +-90 deg (gimbal lock), and independent rounding of alpha
and gamma then errs by up to 5.6 deg. :func:`quat_to_bins` therefore encodes a rotation as the
bin triple whose decoded rotation is *nearest* to it, searching the 3 x 3 x 3 bins around the
rounded angles of both Euler solutions (alpha, beta, gamma) and (alpha + 180, 180 - beta,
gamma + 180). In the (alpha, gamma) plane the bin centres form a rhombic lattice under that
metric, whose covering radius is at most 5 / sqrt(2) = 3.54 deg for every beta; with beta's
2.5 deg the error stays <= sqrt(3.54^2 + 2.5^2) = 4.33 deg everywhere, gimbal region included.

Gripper symmetry. A two-finger hand turned half a turn about its approach axis (tcp z) makes the
same grasp, so a keypose's rotation R and R Rz(180) are one action. The samplers draw both (the
random sampler's R0 is uniform), which would split the rotation targets between two classes
for one behaviour; :func:`canonical_grasp` picks one of the pair for the training targets and
:func:`grasp_geodesic_deg` measures errors up to the symmetry.
"""
from __future__ import annotations

import itertools
import warnings

import numpy as np
from scipy.spatial.transform import Rotation

EULER_SEQUENCE = "xyz"  # SciPy, lower case = extrinsic: R = Rz(gamma) Ry(beta) Rx(alpha)
ROTATION_BINS = 72
_NEIGHBOURS = np.array(list(itertools.product((-1, 0, 1), repeat=3)))  # (27, 3)
HALF_TURN = Rotation.from_euler("z", 180.0, degrees=True)  # about the tcp's approach axis: the hand's symmetry
# The canonical one of R and R Rz(180) has its closing axis (tcp y) along this side. A generic
# direction: the tie (y perpendicular to it) then falls on no axis-aligned grasp, where samples crowd.
SYMMETRY_REFERENCE = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)


def bin_width(bins: int = ROTATION_BINS) -> float:
    """Degrees per bin."""
    return 360.0 / bins


def bins_to_euler(bins: np.ndarray, n_bins: int = ROTATION_BINS) -> np.ndarray:
    """(..., 3) integer bins -> (..., 3) bin-centre angles in degrees, in [-180, 180)."""
    return (np.asarray(bins) + 0.5) * bin_width(n_bins) - 180.0


def bins_to_quat(bins: np.ndarray, n_bins: int = ROTATION_BINS) -> np.ndarray:
    """(N, 3) bins -> (N, 4) unit quaternions (x, y, z, w) with w >= 0."""
    angles = bins_to_euler(np.asarray(bins).reshape(-1, 3), n_bins)
    q = Rotation.from_euler(EULER_SEQUENCE, angles, degrees=True).as_quat()
    return np.where(q[:, 3:] < 0, -q, q)


def _euler_solutions(rotations: Rotation) -> np.ndarray:
    """(N, 2, 3) both Euler-angle solutions in degrees (the second has |beta| >= 90)."""
    with warnings.catch_warnings():  # at gimbal lock SciPy warns and sets gamma = 0: still a valid solution
        warnings.simplefilter("ignore", UserWarning)
        first = rotations.as_euler(EULER_SEQUENCE, degrees=True).reshape(-1, 3)
    second = np.stack([first[:, 0] + 180.0, 180.0 - first[:, 1], first[:, 2] + 180.0], axis=-1)
    return np.stack([first, second], axis=1)


def _angle_bins(angles: np.ndarray, n_bins: int) -> np.ndarray:
    """Bin of each angle in degrees (any value: wrapped into [-180, 180))."""
    return np.floor((np.asarray(angles) + 180.0) / bin_width(n_bins)).astype(np.int64) % n_bins


def _canonical(bins: np.ndarray, n_bins: int) -> np.ndarray:
    """The same rotations with |beta| < 90 deg: (alpha + 180, 180 - beta, gamma + 180) where beta's centre is beyond.

    Bin centres of beta beyond +-90 mirror onto centres inside (90 is a bin edge), so every bin
    triple has an equivalent with |beta| < 90: one rotation, one triple, and q and -q cannot
    pick different triples of the same rotation by rounding.
    """
    angles = bins_to_euler(bins, n_bins)
    flip = np.abs(angles[..., 1]) > 90.0
    mirrored = np.stack([angles[..., 0] + 180.0, 180.0 - angles[..., 1], angles[..., 2] + 180.0], axis=-1)
    return np.where(flip[..., None], _angle_bins(mirrored, n_bins), bins)


def quat_to_bins(quat_xyzw: np.ndarray, n_bins: int = ROTATION_BINS) -> np.ndarray:
    """(N, 4) quaternions (x, y, z, w), any sign and norm -> (N, 3) int64 bins, nearest in angle.

    See the module docstring for why the search (54 candidates per rotation) is needed.
    """
    if n_bins % 4:
        raise ValueError(f"n_bins must be a multiple of 4 (so that +-90 deg is a bin edge), got {n_bins}")
    q = np.asarray(quat_xyzw, dtype=np.float64).reshape(-1, 4)
    q = np.where(q[:, 3:] < 0, -q, q)  # one sign: q and -q then take bit-identical paths
    rotations = Rotation.from_quat(q)
    n = len(rotations)
    rounded = _angle_bins(_euler_solutions(rotations), n_bins)  # (N, 2, 3)
    candidates = _canonical((rounded[:, :, None, :] + _NEIGHBOURS[None, None]) % n_bins, n_bins).reshape(n, -1, 3)
    decoded = Rotation.from_euler(EULER_SEQUENCE, bins_to_euler(candidates.reshape(-1, 3), n_bins), degrees=True)
    repeated = Rotation.from_quat(np.repeat(rotations.as_quat(), candidates.shape[1], axis=0))
    error = (decoded.inv() * repeated).magnitude().reshape(n, -1)
    return candidates[np.arange(n), error.argmin(axis=1)]


def canonical_grasp(quat_xyzw: np.ndarray) -> np.ndarray:
    """(N, 4) quaternions -> the same grasps, each as the one of R and R Rz(180) whose tcp y axis
    has a non-negative component along SYMMETRY_REFERENCE (w >= 0)."""
    rotations = Rotation.from_quat(np.asarray(quat_xyzw, dtype=np.float64).reshape(-1, 4))
    turned = rotations * HALF_TURN
    keep = rotations.as_matrix()[:, :, 1] @ SYMMETRY_REFERENCE >= 0.0
    q = np.where(keep[:, None], rotations.as_quat(), turned.as_quat())
    return np.where(q[:, 3:] < 0, -q, q)


def grasp_geodesic_deg(q_a: np.ndarray, q_b: np.ndarray) -> np.ndarray:
    """(N,) angle in degrees between two grasps, up to the hand's half-turn symmetry (<= 180)."""
    b = Rotation.from_quat(np.asarray(q_b, dtype=np.float64).reshape(-1, 4))
    return np.minimum(geodesic_deg(q_a, b.as_quat()), geodesic_deg(q_a, (b * HALF_TURN).as_quat()))


def geodesic_deg(q_a: np.ndarray, q_b: np.ndarray) -> np.ndarray:
    """(N,) angle in degrees between two (N, 4) arrays of (x, y, z, w) quaternions."""
    a = Rotation.from_quat(np.asarray(q_a, dtype=np.float64).reshape(-1, 4))
    b = Rotation.from_quat(np.asarray(q_b, dtype=np.float64).reshape(-1, 4))
    return np.degrees((a.inv() * b).magnitude())


def ranked_bins(logits: np.ndarray, count: int, separation_deg: float, per_axis: int = 8) -> np.ndarray:
    """(3, bins) Euler-bin logits -> (<= count, 3) bin triples, likeliest first, as grasps apart.

    A triple's score is the sum of its three log-probabilities (the head's axes are independent
    outputs); triples are drawn from the ``per_axis`` likeliest bins of each axis and kept greedily
    when at least ``separation_deg`` from every triple kept before, up to the hand's half turn
    (:func:`grasp_geodesic_deg`): neighbouring bins 5 deg apart are the same grasp to a planner.
    The first triple is the argmax of each axis, the one :func:`actaim2.models.predictor.decode_action` decodes.
    """
    logits = np.asarray(logits, dtype=np.float64)
    log_probs = logits - np.logaddexp.reduce(logits, axis=-1, keepdims=True)
    top = np.argsort(-log_probs, axis=-1, kind="stable")[:, :per_axis]  # (3, per_axis)
    triples = np.array(list(itertools.product(*top)), dtype=np.int64)  # (per_axis^3, 3), argmax triple first
    scores = log_probs[np.arange(3), triples].sum(axis=1)
    triples = triples[np.argsort(-scores, kind="stable")]
    quats = bins_to_quat(triples, logits.shape[-1])
    kept: list[int] = []
    for i in range(len(triples)):
        if len(kept) == count:
            break
        if not kept or grasp_geodesic_deg(np.repeat(quats[i : i + 1], len(kept), axis=0), quats[kept]).min() >= separation_deg:
            kept.append(i)
    return triples[kept]
