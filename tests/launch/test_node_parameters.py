"""Every node declares its parameters from one table (actaim2_ros.params); the YAML files shipped
in <package>/config state the same names and defaults (overlays, loaded after them to change a
few, only known names), and every parameter has a description."""
from __future__ import annotations

import pytest

from actaim2_ros.params import yaml_differences
from harness import REPO


def tables() -> dict[str, dict]:
    from actaim2_control import control_node, scripted_teleop, teleop_node
    from actaim2_perception import calibration_publisher, fusion_node
    from actaim2_policy import bag_player, bag_recorder, episode_runner, policy_node, viz_node
    from actaim2_sim import parameters

    return {"sim_node": {**parameters.DEFAULTS, **parameters.DYNAMIC}, "fusion_node": fusion_node.PARAMETERS,
            "calibration_publisher": calibration_publisher.PARAMETERS, "control_node": control_node.PARAMETERS,
            "policy_node": policy_node.PARAMETERS, "episode_runner": episode_runner.PARAMETERS,
            "bag_player": bag_player.PARAMETERS, "bag_recorder": bag_recorder.PARAMETERS,
            "teleop_node": teleop_node.PARAMETERS, "scripted_teleop": scripted_teleop.PARAMETERS,
            "viz_node": viz_node.PARAMETERS}


# (file, node, overlay)
FILES = [
    ("actaim2_sim/config/sim_node.yaml", "sim_node", False),
    ("actaim2_perception/config/fusion_node.yaml", "fusion_node", False),
    ("actaim2_perception/config/fusion_node_sim_ring5.yaml", "fusion_node", True),
    ("actaim2_perception/config/calibration_publisher.yaml", "calibration_publisher", False),
    ("actaim2_control/config/control_node.yaml", "control_node", False),
    ("actaim2_control/config/teleop_node.yaml", "teleop_node", False),
    ("actaim2_control/config/scripted_teleop.yaml", "scripted_teleop", False),
    ("actaim2_policy/config/policy_node.yaml", "policy_node", False),
    ("actaim2_policy/config/policy_node_azure.yaml", "policy_node", True),
    ("actaim2_policy/config/episode_runner.yaml", "episode_runner", False),
    ("actaim2_policy/config/bag_player.yaml", "bag_player", False),
    ("actaim2_policy/config/bag_recorder.yaml", "bag_recorder", False),
    ("actaim2_policy/config/viz_node.yaml", "viz_node", False),
]


@pytest.mark.parametrize("path, node, overlay", FILES, ids=[f for f, _, _ in FILES])
def test_shipped_yaml_states_the_declared_parameters(path, node, overlay):
    table = tables()[node]
    assert yaml_differences(REPO / path, node, table, overlay) == []
    assert all(isinstance(description, str) and description for _, description in table.values()), node


def test_every_shipped_node_yaml_is_checked():
    shipped = {str(p.relative_to(REPO)) for p in REPO.glob("actaim2_*/config/*.yaml") if "calibration.yaml" not in p.name}
    assert shipped == {f for f, _, _ in FILES}


def test_differences_are_named(tmp_path):
    path = tmp_path / "n.yaml"
    path.write_text("n:\n  ros__parameters:\n    a: 2\n    typo: 1\n    use_sim_time: true\n")
    table = {"a": (1, "x"), "b": ([0.5, 1], "y")}
    assert yaml_differences(path, "n", table) == ["unknown parameter 'typo'", "'a': YAML 2, declared 1",
                                                  "'b' missing (default [0.5, 1])"]
    assert yaml_differences(path, "n", table, overlay=True) == ["unknown parameter 'typo'"]
