"""The shipped config YAMLs state the same defaults the nodes declare."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from actaim2_perception.fusion_node import PARAMETERS

CONFIG = Path(__file__).resolve().parents[2] / "actaim2_perception" / "config"


def test_fusion_node_yaml_matches_declared_defaults():
    params = yaml.safe_load((CONFIG / "fusion_node.yaml").read_text())["fusion_node"]["ros__parameters"]
    assert set(params) == set(PARAMETERS)
    for name, (default, description) in PARAMETERS.items():
        assert params[name] == pytest.approx(default) if isinstance(default, float) else params[name] == default, name
        assert description


def test_example_calibration_is_valid():
    from actaim2.perception.calibration import load_calibration

    parent, transforms = load_calibration(CONFIG / "azure_kinect_calibration.yaml")
    assert parent == "world" and list(transforms) == ["camera_base"]
    # The example camera stands in front of the robot and looks back at it, downwards.
    T = transforms["camera_base"]
    assert T[0, 3] > 1.0 and T[:3, 0] @ [-1.0, 0.0, 0.0] > 0.7 and T[2, 0] < 0


def test_shipped_fusion_node_yamls_name_a_perception_configuration():
    from actaim2.perception.config import load_perception_config

    rigs = {}
    for path in sorted(CONFIG.glob("fusion_node*.yaml")):
        params = yaml.safe_load(path.read_text())["fusion_node"]["ros__parameters"]
        rigs[path.name] = load_perception_config(params.get("perception_config", PARAMETERS["perception_config"][0])).rig
    assert rigs == {"fusion_node.yaml": "azure_kinect", "fusion_node_sim_ring5.yaml": "ring5"}
