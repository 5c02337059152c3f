"""Static transform chains as the Azure Kinect driver and calibration_publisher publish them."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.geometry import invert, pose_to_matrix
from actaim2.perception.calibration import load_calibration
from actaim2.perception.static_tf import StaticTransformBuffer, UnknownFrameError


def test_chain_is_composed_in_both_directions():
    T_world_base = pose_to_matrix([1.0, 0.5, 0.8], [0.0, 0.0, 0.7071068, 0.7071068])
    T_base_depth = pose_to_matrix([0.0, 0.03, 0.0], [-0.5, 0.5, -0.5, 0.5])
    buffer = StaticTransformBuffer()
    buffer.set_transform("camera_base", "depth_camera_link", T_base_depth)  # arrival order must not matter
    buffer.set_transform("world", "camera_base", T_world_base)
    np.testing.assert_allclose(buffer.lookup("world", "depth_camera_link"), T_world_base @ T_base_depth, atol=1e-12)
    np.testing.assert_allclose(buffer.lookup("depth_camera_link", "world"), invert(T_world_base @ T_base_depth), atol=1e-12)
    np.testing.assert_allclose(buffer.lookup("world", "world"), np.eye(4))


def test_sibling_frames_and_replacement():
    buffer = StaticTransformBuffer()
    buffer.set_transform("world", "a", pose_to_matrix([1, 0, 0], [0, 0, 0, 1]))
    buffer.set_transform("world", "b", pose_to_matrix([0, 2, 0], [0, 0, 0, 1]))
    np.testing.assert_allclose(buffer.lookup("a", "b")[:3, 3], [-1, 2, 0])
    buffer.set_transform("world", "b", pose_to_matrix([0, 3, 0], [0, 0, 0, 1]))  # re-calibrated
    np.testing.assert_allclose(buffer.lookup("a", "b")[:3, 3], [-1, 3, 0])


def test_unknown_frame_names_the_known_ones():
    buffer = StaticTransformBuffer()
    buffer.set_transform("world", "camera_base", np.eye(4))
    assert not buffer.can_transform("world", "depth_camera_link")
    with pytest.raises(UnknownFrameError, match="known frames: camera_base, world"):
        buffer.lookup("world", "depth_camera_link")


def test_calibration_yaml(tmp_path):
    good = tmp_path / "calib.yaml"
    good.write_text("transforms:\n  camera_base: [[1,0,0,0.5],[0,1,0,0],[0,0,1,1.0],[0,0,0,1]]\n")
    parent, transforms = load_calibration(good)
    assert parent == "world" and list(transforms) == ["camera_base"]
    np.testing.assert_allclose(transforms["camera_base"][:3, 3], [0.5, 0, 1.0])
    bad = tmp_path / "bad.yaml"
    bad.write_text("transforms:\n  cam: [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n")
    with pytest.raises(ValueError, match="not a rotation"):
        load_calibration(bad)
    bad.write_text("transforms: {}\n")
    with pytest.raises(ValueError, match="non-empty 'transforms'"):
        load_calibration(bad)
