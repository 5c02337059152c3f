"""PerceptionConfig: one YAML per rig, a stable digest, mismatches refused by name."""
from __future__ import annotations

import subprocess
import sys
from dataclasses import fields

import numpy as np
import pytest

from actaim2.perception.config import (
    CAPTURE_FIELDS,
    CONFIG_DIR,
    VIEW_FIELDS,
    PerceptionConfig,
    PerceptionMismatchError,
    capture_part,
    check_compatible,
    load_perception_config,
    save_perception_config,
)
from actaim2.sim.cameras import RIGS
from actaim2.sim.env import WORKSPACE_CENTER


def test_one_yaml_per_rig_and_the_cube_is_where_the_simulator_places_objects():
    assert sorted(p.stem for p in CONFIG_DIR.glob("*.yaml")) == sorted(RIGS)
    for rig in RIGS:
        config = load_perception_config(rig)
        assert config.rig == rig and config.render_path == "sapien" and config.remove_robot_views
        np.testing.assert_allclose(config.center, WORKSPACE_CENTER)
    # Capture and view fields partition the configuration.
    assert sorted(CAPTURE_FIELDS + VIEW_FIELDS) == sorted(f.name for f in fields(PerceptionConfig))


def test_dict_and_yaml_round_trips(tmp_path):
    config = load_perception_config("ring5").replace(resolution=224, channels=("x", "y", "z", "depth"))
    assert PerceptionConfig.from_dict(config.to_dict()) == config
    save_perception_config(config, tmp_path / "mine.yaml")
    assert load_perception_config(tmp_path / "mine.yaml") == config
    assert load_perception_config(str(tmp_path / "mine.yaml")).digest() == config.digest()


def test_digest_is_stable_across_processes_and_float_noise_and_changes_with_every_field():
    config = load_perception_config("ring5")
    other_process = subprocess.run(
        [sys.executable, "-c", "from actaim2.perception.config import load_perception_config as l; print(l('ring5').digest())"],
        capture_output=True, text=True, check=True,
    ).stdout.strip()
    assert other_process == config.digest() and len(config.digest()) == 16
    assert config.replace(half_extent=0.6 + 1e-9).digest() == config.digest()
    changed = {"rig": "azure_kinect", "center": (0.7, 0.0, 0.4), "half_extent": 0.5, "remove_robot_views": False,
               "self_filter_margin": 0.02, "render_path": "raycast", "voxel_size": 0.004, "outlier_neighbors": 8,
               "outlier_std_ratio": 1.5, "resolution": 224, "channels": ("r", "g", "b"), "splat_radius": 0.8,
               "splat_depth_tolerance": 0.03}
    assert set(changed) == {f.name for f in fields(PerceptionConfig)} - {"normalisation"}  # its only value is the default
    digests = {config.replace(**{name: value}).digest() for name, value in changed.items()}
    assert len(digests) == len(changed) and config.digest() not in digests


def test_a_mismatch_is_refused_naming_the_fields_and_values():
    ring5 = load_perception_config("ring5")
    serving = ring5.replace(half_extent=0.5, resolution=224)
    assert ring5.diff(serving) == ["half_extent", "resolution"]
    with pytest.raises(PerceptionMismatchError) as err:
        check_compatible(ring5, serving, sides=("checkpoint", "serving"))
    text = str(err.value)
    assert "half_extent (checkpoint 0.6, serving 0.5)" in text and "resolution (checkpoint 128, serving 224)" in text
    check_compatible(ring5.to_dict(), ring5)  # equal: nothing raised
    # A dataset fixes only the capture fields: a run may choose its own views ...
    check_compatible(capture_part(ring5), serving.replace(half_extent=0.6), CAPTURE_FIELDS, ("dataset", "training run"))
    # ... but not another rig or render path.
    with pytest.raises(PerceptionMismatchError, match=r"rig \(dataset 'ring5', training run 'azure_kinect'\).*render_path"):
        check_compatible(capture_part(ring5), load_perception_config("azure_kinect").replace(render_path="raycast"),
                         CAPTURE_FIELDS, ("dataset", "training run"))
    with pytest.raises(PerceptionMismatchError, match="render_path .*'<missing>'"):
        check_compatible({k: v for k, v in capture_part(ring5).items() if k != "render_path"}, ring5, CAPTURE_FIELDS)


def test_bad_configurations_say_what_is_wrong(tmp_path):
    with pytest.raises(FileNotFoundError, match="known rigs"):
        load_perception_config("ring7")
    (tmp_path / "typo.yaml").write_text("rig: ring5\ncenter: [0.75, 0.0, 0.4]\nhalf_extent: 0.6\nresolutoin: 224\n")
    with pytest.raises(ValueError, match="resolutoin"):
        load_perception_config(tmp_path / "typo.yaml")
    with pytest.raises(ValueError, match="render_path 'vulkan'"):
        load_perception_config("ring5").replace(render_path="vulkan")
    with pytest.raises(ValueError, match="channels"):
        load_perception_config("ring5").replace(channels=("r", "intensity"))
    with pytest.raises(ValueError, match="splat_radius"):
        load_perception_config("ring5").replace(splat_radius=1.5)
