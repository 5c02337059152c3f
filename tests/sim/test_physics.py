"""Object physics: gravity on every link, joints that hold, lids with a balance point, bistable
toggles, masses from materials, and the per-category table behind them."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.sim.env import SimEnv
from actaim2.sim.objects import catalog
from actaim2.sim.objects.categories import LAYOUTS
from actaim2.sim.objects.mass import link_mass_properties
from actaim2.sim.objects.physics_table import (
    BISTABLE,
    COUNTERBALANCED,
    JOINT_TABLE,
    MATERIALS,
    category_dynamics,
    part_material,
)


def instance_with(category: str, layout: str, k: int = 0) -> int:
    """The k-th catalogued instance built with ``layout``."""
    return [i for i in catalog.category_instances(category) if LAYOUTS[category][i % len(LAYOUTS[category])] == layout][k]


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    return SimEnv("panda", cache_dir=tmp_path_factory.mktemp("objects"))


def fractions(info) -> np.ndarray:
    return (info.dof_initial - info.dof_lower) / (info.dof_upper - info.dof_lower)


@pytest.mark.parametrize("category, layout, fraction", [
    ("storage_furniture", "drawers", 0.5),   # drawers on runners
    ("door", "pull", 0.5),                   # a hinge on a vertical axis
    ("window", "vertical", 0.5),             # a sash lifted against gravity, on its balances
    ("faucet", "side_lever", 0.5),           # a lever on a horizontal axis, held by the cartridge
    ("switch", "slider", 0.5),               # a vertical dimmer slide
    ("safe", "top_lid", 0.5),                # a heavy lid on gas struts
    ("box", "hinged_lid", 1.0),              # a lid opened past its balance point rests on its stop
])
def test_released_parts_hold_still_under_gravity(env, category, layout, fraction):
    info = env.reset(category, instance_with(category, layout), seed=1, dof_fraction=fraction)
    obj = env.object
    for joint, d in zip(obj.joints, obj.dynamics.dynamics):
        assert joint.child_link.disable_gravity == (d.behaviour == COUNTERBALANCED), joint.name
    assert not obj.links[0].disable_gravity
    np.testing.assert_allclose(fractions(info), fraction, atol=0.01)  # it rests where it was put
    np.testing.assert_allclose(env.object_dof(), info.dof_initial, atol=1e-6)  # dof_initial is the read-back state
    env.step(int(2.0 / env.timestep))
    np.testing.assert_allclose(env.object_dof(), info.dof_initial, atol=1e-3)


def test_a_lid_falls_shut_below_its_balance_point_and_stays_open_past_it(env):
    instance = instance_with("box", "hinged_lid")
    info = env.reset("box", instance, seed=1, dof_fraction=0.3)
    assert env.object.dynamics.dynamics[0].behaviour != COUNTERBALANCED
    assert fractions(info)[0] < 0.02, "a lid released at 30% of its range must fall shut"
    upper = float(info.dof_upper[0])
    assert upper > np.radians(100)  # the range reaches past the vertical balance point
    past = (np.radians(95) - info.dof_lower[0]) / (upper - info.dof_lower[0])
    info = env.reset("box", instance, seed=1, dof_fraction=past)
    assert fractions(info)[0] > 0.99, "a lid released past its balance point must fall open onto its stop"


def test_toggles_are_bistable(env):
    instance = instance_with("switch", "toggle")
    info = env.reset("switch", instance, seed=1, dof_fraction=0.4)
    assert all(d.behaviour == BISTABLE for d in env.object.dynamics.dynamics)
    np.testing.assert_allclose(fractions(info), 0.0, atol=0.01)
    info = env.reset("switch", instance, seed=1, dof_fraction=0.6)
    np.testing.assert_allclose(fractions(info), 1.0, atol=0.01)
    env.step(int(1.0 / env.timestep))
    np.testing.assert_allclose(env.object_dof(), info.dof_initial, atol=1e-3)


def test_masses_come_from_volumes_and_materials(env):
    instance = instance_with("door", "pull")
    model = catalog.generate("door", instance)
    leaf = next(link for link in model.links if link.name == "door")
    densities = [MATERIALS[s.material or leaf.material].density for s in leaf.shapes]
    expected, _, _ = link_mass_properties(leaf.shapes, densities)
    env.reset("door", instance, seed=1)
    assert env.object.link("door").mass == pytest.approx(expected, rel=1e-3)
    panel = max(leaf.shapes, key=lambda s: np.prod(s.size))  # the leaf board itself: MDF
    assert expected > MATERIALS["mdf"].density * np.prod(panel.size)
    assert part_material("refrigerator", "door").density < part_material("door", "door").density < part_material("safe", "door").density


def test_every_generated_part_has_its_own_table_row_with_a_source():
    for category in catalog.list_categories():
        for instance in catalog.category_instances(category)[:len(LAYOUTS[category])]:
            for joint in catalog.generate(category, instance).movable_joints():
                d = category_dynamics(category, joint.semantic)
                assert d.source and d.source != JOINT_TABLE[("*", "*")].source, (category, joint.semantic)
                assert joint.friction > 0.0 and joint.damping > 0.0
    # real PartNet-Mobility labels and unknown categories still get dynamics
    assert category_dynamics("storage_furniture", "rotation_door") == category_dynamics("storage_furniture", "door")
    assert category_dynamics("microwave", "").friction > 0.0
