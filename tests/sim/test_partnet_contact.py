"""Real PartNet-Mobility objects are physically there: what touches them is stopped or moves them.

On the shared real objects (a cabinet with a drawer and a door, a cabinet with two doors, a
table with a drawer, a faucet, a box) and on a generated cabinet: a sphere dropped onto a top
surface rests on it; the arm, on joint targets (IK, no planner), pushing a door, a drawer or a
lever moves its DoF; half-open parts at rest stay at rest (an object's links do not collide
with each other); with the hull cache cold the load warns and the object still collides; and
the random and heuristic-grasp samplers succeed on a real cabinet.
"""
from __future__ import annotations

import logging

import numpy as np
import pytest
import sapien

from actaim2.rollout.push import ScriptedPush
from actaim2.sim.contacts import ContactMonitor
from actaim2.sim.env import SimEnv
from actaim2.sim.objects.hulls import HullCache
from actaim2.sim.objects.mesh import write_obj
from actaim2.sim.objects.physics_table import COUNTERBALANCED
from actaim2.sim.objects.surface import surface_points
from partnet_shared import box, shared_partnet

SPHERE_RADIUS = 0.015
DRAWER_AND_DOOR, TWO_DOORS, TABLE, FAUCET, BOX, OVEN = "40147", "45780", "22241", "1053", "102456", "101773"
DROP_DOWN_FLAP, LIFT_UP_FLAP = "45166", "46408"  # cabinets whose door hinges on its bottom / top edge


@pytest.fixture(scope="module")
def env(tmp_path_factory) -> SimEnv:
    env = SimEnv("panda", cache_dir=tmp_path_factory.mktemp("objects"))
    env.hulls = HullCache(tmp_path_factory.mktemp("hulls"))  # cold: one hull per mesh, as CI has it
    return env


@pytest.fixture(scope="module")
def pusher(env) -> ScriptedPush:
    return ScriptedPush(env)


def reset(env: SimEnv, name: str, dof_fraction: float = 0.5):
    if name == "generated":
        return env.reset("storage_furniture", 0, seed=0, jitter=False, dof_fraction=dof_fraction)
    return env.reset(folder=shared_partnet() / name, seed=0, jitter=False, dof_fraction=dof_fraction)


def flat_top_spot(env: SimEnv, cell: float = 0.01, patch: int = 2) -> tuple[np.ndarray, float]:
    """(xy, height) of the flat upward surface nearest the object's centre, among the highest:
    a (2 patch + 1)-cell square of the object's top view whose tops lie within 3 mm of each other,
    at most 5 cm below the object's top."""
    points = surface_points(env.object.links, spacing=0.005)
    lo = points[:, :2].min(axis=0)
    ij = np.floor((points[:, :2] - lo) / cell).astype(int)
    top = np.full(ij.max(axis=0) + 1, -np.inf)
    np.maximum.at(top, (ij[:, 0], ij[:, 1]), points[:, 2])
    highest, centre = top.max(), (points[:, :2].min(axis=0) + points[:, :2].max(axis=0)) / 2
    best = None
    for i in range(patch, top.shape[0] - patch):
        for j in range(patch, top.shape[1] - patch):
            square = top[i - patch:i + patch + 1, j - patch:j + patch + 1]
            if top[i, j] < highest - 0.05 or np.ptp(square) > 0.003:
                continue
            xy = lo + (np.array([i, j]) + 0.5) * cell
            if best is None or np.linalg.norm(xy - centre) < np.linalg.norm(best[0] - centre):
                best = (xy, float(top[i, j]))
    assert best is not None, "no flat top surface on the object"
    return best


def drop_sphere(env: SimEnv, xy: np.ndarray, height: float, seconds: float = 1.0):
    builder = env.scene.create_actor_builder()
    builder.add_sphere_collision(radius=SPHERE_RADIUS)
    sphere = builder.build(name="probe_sphere")
    sphere.set_pose(sapien.Pose([xy[0], xy[1], height]))
    env.step(int(seconds / env.timestep))
    position = np.asarray(sphere.get_pose().p, dtype=float)
    env.scene.remove_entity(sphere)
    return position


@pytest.mark.parametrize("name", ["generated", DRAWER_AND_DOOR, TABLE, BOX])
def test_a_sphere_dropped_on_the_top_surface_rests_on_it_with_the_hull_cache_cold(env, name, caplog):
    with caplog.at_level(logging.WARNING, logger="actaim2.sim.objects"):
        reset(env, name, dof_fraction=0.0)
    if name != "generated":
        assert "actaim2 prepare-objects" in caplog.text  # no decomposition: one hull per mesh, said so
    xy, height = flat_top_spot(env)
    rest = drop_sphere(env, xy, height + 0.05)
    assert abs(rest[2] - (height + SPHERE_RADIUS)) < 0.005, f"{name}: the sphere ended at z={rest[2]:.3f}, on a top at {height:.3f}"
    assert np.linalg.norm(rest[:2] - xy) < 0.01, f"{name}: the sphere rolled from {xy} to {rest[:2]}"


def test_the_contact_monitor_sees_a_push_and_not_a_move_in_free_space(env, pusher):
    monitor = ContactMonitor(env)
    try:
        reset(env, DRAWER_AND_DOOR)
        monitor.reset()
        env.follow_trajectory(np.array([1.0]), (env.spec.home + 0.3)[None, :])  # away from the object
        assert not monitor.touched
        assert pusher.push(1).moved > 0.1
        assert monitor.touched
    finally:
        env.step_observers.remove(monitor)


@pytest.mark.parametrize("name, dof", [(DRAWER_AND_DOOR, 1), (DRAWER_AND_DOOR, 0), (TWO_DOORS, 0), (TABLE, 0),
                                       (FAUCET, 0), ("generated", 0)])
def test_the_arm_pushing_a_part_moves_it(env, pusher, name, dof):
    info = reset(env, name)
    result = pusher.push(dof)
    assert result.pushed, result.message
    assert result.moved > 0.1, f"{name} {info.dof_names[dof]}: moved {result.moved:.1%} of its range ({result.message})"


DOUBLE_DOOR_URDF = """<?xml version="1.0"?>
<robot name="double_door">
  <link name="base"/>
  <link name="link_body"><collision><geometry><mesh filename="textured_objs/body.obj"/></geometry></collision></link>
  <link name="link_left"><collision><geometry><mesh filename="textured_objs/left.obj"/></geometry></collision></link>
  <link name="link_right"><collision><geometry><mesh filename="textured_objs/right.obj"/></geometry></collision></link>
  <joint name="joint_body" type="fixed"><parent link="base"/><child link="link_body"/></joint>
  <joint name="joint_left" type="revolute"><parent link="link_body"/><child link="link_left"/>
    <origin xyz="-0.3 -0.4 0"/><axis xyz="0 0 -1"/><limit lower="0" upper="1.5"/></joint>
  <joint name="joint_right" type="revolute"><parent link="link_body"/><child link="link_right"/>
    <origin xyz="-0.3 0.4 0"/><axis xyz="0 0 1"/><limit lower="0" upper="1.5"/></joint>
</robot>
"""


def double_door(folder):
    """Two doors on one body whose panels overlap by 4 cm where they meet, as PartNet parts
    interpenetrate at their seams (siblings: PhysX skips parent-child pairs by itself)."""
    (folder / "textured_objs").mkdir(parents=True)
    write_obj(folder / "textured_objs/body.obj", [box((-0.3, -0.4, 0.0), (0.3, 0.4, 1.0))])
    write_obj(folder / "textured_objs/left.obj", [box((-0.02, 0.0, 0.02), (0.0, 0.42, 0.98))])
    write_obj(folder / "textured_objs/right.obj", [box((-0.02, -0.42, 0.02), (0.0, 0.0, 0.98))])
    (folder / "mobility.urdf").write_text(DOUBLE_DOOR_URDF)
    (folder / "meta.json").write_text('{"model_cat": "StorageFurniture"}')
    (folder / "semantics.txt").write_text("link_left hinge rotation_door\nlink_right hinge rotation_door\nlink_body heavy body\n")
    return folder


@pytest.mark.parametrize("name", [DRAWER_AND_DOOR, TWO_DOORS, TABLE, FAUCET, BOX, OVEN, DROP_DOWN_FLAP, LIFT_UP_FLAP,
                                  "overlapping doors"])
def test_parts_at_rest_stay_at_rest(env, name, tmp_path):
    """The links of one object do not collide with each other: PartNet parts interpenetrate at
    their seams, and if they collided PhysX would push the parts apart. Flaps (doors on a
    horizontal hinge) are held where they are left, as their stays hold them, and one hinged
    at the bottom edge swings above the floor (the object stands raised)."""
    if name == "overlapping doors":
        info = env.reset(folder=double_door(tmp_path / "doors"), seed=0, jitter=False, dof_fraction=0.0)
        np.testing.assert_allclose(info.dof_initial, info.dof_lower, atol=1e-3)  # the reset's settling pushed nothing
    else:
        info = reset(env, name)
    if name in (DROP_DOWN_FLAP, LIFT_UP_FLAP):
        np.testing.assert_allclose(info.dof_initial, (info.dof_lower + info.dof_upper) / 2, atol=0.01)
        assert all(d.behaviour == COUNTERBALANCED for d in env.object.dynamics.dynamics)
        assert (env.object.base_height > 0.02) == (name == DROP_DOWN_FLAP)
    env.step(int(2.0 / env.timestep))
    span = info.dof_upper - info.dof_lower
    drift = np.abs(env.object_dof() - info.dof_initial) / span
    assert np.all(drift < 0.01), f"{name}: parts drifted by {np.round(drift, 3).tolist()} of their ranges"
