"""A Keypose is checked once, where it is made (Keypose.__post_init__)."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.keypose import Keypose, check_phase

UP = np.array([0.0, 0.0, 0.0, 1.0])


@pytest.mark.parametrize(("phase", "position", "quat", "reason"), [
    (4, np.zeros(3), UP, r"unknown phase 4: expected one of 0 \(INIT\), 1 \(REACH\), 2 \(GRASP\), 3 \(MANIPULATE\)"),
    (0, np.array([0.1, np.nan, 0.2]), UP, "position .* is not finite"),
    (0, np.zeros(2), UP, "position .* is not finite"),
    (0, np.zeros(3), np.array([0.0, 0.0, 0.0, 0.5]), "orientation .* is not a unit quaternion"),
    (0, np.zeros(3), np.array([0.0, 0.0, np.inf, 1.0]), "orientation .* is not a unit quaternion"),
    (0, np.zeros(3), np.zeros(3), "orientation .* is not a unit quaternion"),
], ids=["phase", "nan_position", "short_position", "half_length_quaternion", "infinite_quaternion", "short_quaternion"])
def test_a_malformed_keypose_is_refused_naming_what_is_wrong(phase, position, quat, reason):
    with pytest.raises(ValueError, match=reason):
        Keypose(phase, position, quat, False)


def test_a_nearly_unit_quaternion_is_normalised():
    keypose = Keypose(np.int64(2), [0.1, 0.2, 0.3], np.array([0.0, 0.0, 0.0, 1.0005]), True)
    assert keypose.phase == 2 and type(keypose.phase) is int
    np.testing.assert_array_equal(keypose.quat_xyzw, UP)
    np.testing.assert_array_equal(keypose.position, [0.1, 0.2, 0.3])
    assert Keypose.from_json(keypose.to_json()).to_json() == keypose.to_json()


def test_a_quaternion_unit_up_to_rounding_is_kept_as_given():
    quat = np.array([0.6607570895249227, 0.4673198350725929, 0.26231677632709155, 0.525549378505617])
    assert np.linalg.norm(quat) != 1.0
    np.testing.assert_array_equal(Keypose(0, np.zeros(3), quat, False).quat_xyzw, quat)


def test_the_phase_check_is_the_one_requests_and_the_planner_use():
    assert check_phase(3) == 3
    with pytest.raises(ValueError, match="unknown phase -1"):
        check_phase(-1)
