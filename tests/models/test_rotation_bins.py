"""Rotation bins: the geodesic error bound everywhere (gimbal region included), sign invariance, conventions,
the hand's half-turn symmetry."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.geometry import xyzw_to_wxyz
from actaim2.models.rotation_bins import (
    HALF_TURN,
    ROTATION_BINS,
    SYMMETRY_REFERENCE,
    bins_to_euler,
    bins_to_quat,
    canonical_grasp,
    geodesic_deg,
    grasp_geodesic_deg,
    quat_to_bins,
    ranked_bins,
)

BOUND_DEG = 4.4  # sqrt(3) * 2.5 deg = 4.33 deg, the covering radius of 5-degree Euler bins


def _near_gimbal(n: int, rng: np.random.Generator) -> np.ndarray:
    """Quaternions (x, y, z, w) whose pitch lies within 1 deg of +-90 deg."""
    pitch = rng.choice([-1.0, 1.0], n) * (90.0 - rng.uniform(0.0, 1.0, n))
    angles = np.stack([rng.uniform(-180, 180, n), pitch, rng.uniform(-180, 180, n)], axis=-1)
    return Rotation.from_euler("xyz", angles, degrees=True).as_quat()


def test_geodesic_error_is_bounded_on_10k_rotations_1k_near_gimbal_lock():
    rng = np.random.default_rng(0)
    quats = np.concatenate([Rotation.random(9000, random_state=1).as_quat(), _near_gimbal(1000, rng)])
    bins = quat_to_bins(quats)
    assert bins.shape == (10000, 3) and bins.min() >= 0 and bins.max() < ROTATION_BINS
    error = geodesic_deg(quats, bins_to_quat(bins))
    assert error.max() <= BOUND_DEG, (error.max(), np.argmax(error))
    assert error[9000:].max() <= BOUND_DEG
    assert np.abs(bins_to_euler(bins)[:, 1]).max() < 90.0  # one triple per rotation: pitch inside +-90


def test_q_and_minus_q_give_the_same_bins_and_scale_does_not_matter():
    quats = Rotation.random(2000, random_state=2).as_quat()
    bins = quat_to_bins(quats)
    np.testing.assert_array_equal(quat_to_bins(-quats), bins)
    np.testing.assert_array_equal(quat_to_bins(3.0 * quats), bins)


def test_convention_is_xyzw_and_extrinsic_xyz():
    """A 90 deg yaw is (0, 0, sin 45, cos 45) in (x, y, z, w): read as (w, x, y, z) it would be
    another rotation (the authors' bug). Its bins decode to roll, pitch +-2.5 and yaw 87.5 or 92.5 deg."""
    q = np.array([[0.0, 0.0, np.sqrt(0.5), np.sqrt(0.5)]])
    angles = bins_to_euler(quat_to_bins(q))[0]
    np.testing.assert_allclose(np.abs(angles), [2.5, 2.5, angles[2]], atol=1e-9)
    assert min(abs(angles[2] - 87.5), abs(angles[2] - 92.5)) < 1e-9
    assert geodesic_deg(q, bins_to_quat(quat_to_bins(q)))[0] <= BOUND_DEG
    assert geodesic_deg(xyzw_to_wxyz(q), bins_to_quat(quat_to_bins(q)))[0] > 30.0
    # Extrinsic x-y-z: R = Rz(gamma) Ry(beta) Rx(alpha).
    a, b, g = np.radians([30.0, 20.0, -40.0])
    rx = Rotation.from_rotvec([a, 0, 0]).as_matrix()
    ry = Rotation.from_rotvec([0, b, 0]).as_matrix()
    rz = Rotation.from_rotvec([0, 0, g]).as_matrix()
    q = Rotation.from_matrix(rz @ ry @ rx).as_quat()[None]
    np.testing.assert_allclose(bins_to_euler(quat_to_bins(q))[0], [32.5, 22.5, -37.5])


def test_decoded_quaternions_are_unit_with_nonnegative_w():
    q = bins_to_quat(np.random.default_rng(3).integers(0, ROTATION_BINS, (500, 3)))
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-12)
    assert (q[:, 3] >= 0).all()


def test_canonical_grasp_maps_both_half_turns_of_a_grasp_to_one_rotation():
    rotations = Rotation.random(500, random_state=3)
    turned = rotations * HALF_TURN
    a, b = canonical_grasp(rotations.as_quat()), canonical_grasp(turned.as_quat())
    assert np.allclose(a, b, atol=1e-9)
    # it is one of the two, with the closing axis on the reference's side
    assert np.all((geodesic_deg(a, rotations.as_quat()) < 1e-6) | (geodesic_deg(a, turned.as_quat()) < 1e-6))
    assert np.all(Rotation.from_quat(a).as_matrix()[:, :, 1] @ SYMMETRY_REFERENCE >= 0.0)
    assert np.all(a[:, 3] >= 0.0)


def test_grasp_geodesic_ignores_the_half_turn_and_nothing_else():
    rotations = Rotation.random(200, random_state=4)
    assert np.allclose(grasp_geodesic_deg(rotations.as_quat(), (rotations * HALF_TURN).as_quat()), 0.0, atol=1e-6)
    tilted = rotations * Rotation.from_euler("x", 30.0, degrees=True)  # about the closing-normal axis: a real change
    assert np.allclose(grasp_geodesic_deg(rotations.as_quat(), tilted.as_quat()), 30.0, atol=1e-6)


def test_ranked_bins_start_at_the_argmax_and_keep_grasps_apart():
    rng = np.random.default_rng(5)
    logits = rng.normal(0.0, 1.0, (3, ROTATION_BINS))
    logits[np.arange(3), [10, 30, 50]] += 6.0  # a clear argmax ...
    logits[np.arange(3), [11, 31, 50]] += 5.5  # ... a neighbour 5 deg off it (the same grasp) ...
    logits[0, 46] += 5.0  # ... and a roll 180 deg off it
    triples = ranked_bins(logits, 4, 30.0)
    assert triples.shape == (4, 3)
    np.testing.assert_array_equal(triples[0], logits.argmax(axis=-1))
    quats = bins_to_quat(triples)
    for i in range(4):
        for j in range(i):
            assert grasp_geodesic_deg(quats[i:i + 1], quats[j:j + 1])[0] >= 30.0
    assert [11, 31, 50] not in triples.tolist()  # 5 deg off the first: skipped
    assert len(ranked_bins(logits, 1, 30.0)) == 1
    # a separation no two grasps have: only the argmax
    assert len(ranked_bins(logits, 4, 181.0)) == 1
