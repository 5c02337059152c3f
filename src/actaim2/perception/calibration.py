"""Camera extrinsics from a calibration YAML (a hand-eye result), for rigs without /tf_static.

Format (one file per rig)::

    parent_frame: world            # optional, default "world"
    transforms:                    # child frame_id -> T_parent_child, 4x4 row-major, metres
      camera_base: [[1, 0, 0, 0.6], [0, 1, 0, 0.0], [0, 0, 1, 1.2], [0, 0, 0, 1]]
      depth_camera_link: [[...], [...], [...], [...]]

Children may refer to each other through /tf_static chains; each entry here is one edge
``parent_frame -> child``. ``calibration_publisher`` publishes exactly these edges on /tf_static so
that recorded bags carry the extrinsics.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml


def validate_transform(T: np.ndarray, name: str) -> np.ndarray:
    """A rigid 4x4 transform or ValueError saying what is wrong with it."""
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"{name}: expected a 4x4 matrix, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError(f"{name}: non-finite entries")
    if not np.allclose(T[3], [0, 0, 0, 1], atol=1e-6):
        raise ValueError(f"{name}: last row must be [0, 0, 0, 1]")
    R = T[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-4) or np.linalg.det(R) < 0:
        raise ValueError(f"{name}: the 3x3 block is not a rotation")
    return T


def load_calibration(path: str | Path) -> tuple[str, dict[str, np.ndarray]]:
    """(parent_frame, {child_frame: T_parent_child}) from a calibration YAML."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML: {exc}") from exc
    if not isinstance(data, dict) or not isinstance(data.get("transforms"), dict) or not data["transforms"]:
        raise ValueError(f"{path}: expected a mapping with a non-empty 'transforms' mapping (child frame -> 4x4)")
    parent = str(data.get("parent_frame", "world"))
    transforms = {str(child): validate_transform(T, f"{path}: {child}") for child, T in data["transforms"].items()}
    return parent, transforms
