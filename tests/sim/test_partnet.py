"""Real PartNet-Mobility folders through the library: checks, categories, continuous joints and
negative limits, scale and the workspace cube, and convex decomposition through the hull cache.

The five shared objects load without decomposition (their meshes get one hull each, with a
warning): only a tiny hand-made object is decomposed here (CI decomposes nothing else)."""
from __future__ import annotations

import logging

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from actaim2.sim.env import SimEnv
from actaim2.sim.objects.errors import ObjectLoadError
from actaim2.sim.objects.hulls import HullCache
from actaim2.sim.objects.mesh import Mesh, read_obj, solid_fraction
from actaim2.sim.objects.partnet import CONTINUOUS_RANGE, category_name, read_object_folder
from actaim2.sim.objects.prepare import find_object_folders, prepare_objects
from actaim2.sim.objects.sizing import (
    WORKSPACE_CENTER,
    WORKSPACE_HALF_EXTENT,
    WORKSPACE_MARGIN,
    fit_object,
)
from partnet_shared import (
    BAR_GAP_POINT,
    HANDLE,
    OBJECTS,
    bad_folders,
    box,
    make_object,
    shared_partnet,
    urdf_limits,
)


@pytest.fixture(scope="module")
def env() -> SimEnv:
    return SimEnv("panda")


def inside_any_shape(link, point_world: np.ndarray) -> bool:
    """Whether a world point lies inside one of the link's convex collision shapes."""
    for shape in link.collision_shapes:
        T = link.entity_pose.to_transformation_matrix() @ shape.local_pose.to_transformation_matrix()
        v = shape.get_vertices() * np.asarray(shape.scale) @ T[:3, :3].T + T[:3, 3]
        eq = ConvexHull(v).equations
        if np.all(eq[:, :3] @ point_world + eq[:, 3] <= 1e-6):
            return True
    return False


def movable_links_box(env: SimEnv) -> tuple[np.ndarray, np.ndarray]:
    obj = env.object
    names = {j.child_link.name for j in obj.joints}
    boxes = np.array([link.compute_global_aabb_tight() for link in obj.links if link.name in names and link.collision_shapes])
    return boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)


# -- the shared real objects ------------------------------------------------------------------------
def test_shared_objects_load_with_their_dofs_limits_and_inside_the_workspace(env, tmp_path, caplog):
    root = shared_partnet()
    env.hulls = HullCache(tmp_path / "hulls")  # empty: one hull per mesh, and a warning
    cube_lo, cube_hi = WORKSPACE_CENTER - WORKSPACE_HALF_EXTENT, WORKSPACE_CENTER + WORKSPACE_HALF_EXTENT
    for name, (category, joints) in OBJECTS.items():
        with caplog.at_level(logging.WARNING, logger="actaim2.sim.objects"):
            info = env.reset(folder=root / name, seed=1, dof_fraction=0.5)
        assert "actaim2 prepare-objects" in caplog.text
        caplog.clear()
        assert (info.object_id, info.category, info.instance) == (name, category, -1)
        assert info.dof_names == list(joints)
        lower, upper = urdf_limits(joints, env.object.scale)
        np.testing.assert_allclose(info.dof_lower, lower, atol=1e-3)
        np.testing.assert_allclose(info.dof_upper, upper, atol=1e-3)
        assert np.all((info.dof_initial >= info.dof_lower - 1e-6) & (info.dof_initial <= info.dof_upper + 1e-6))
        # every movable link, over each joint's whole range, stays inside the workspace cube
        obj = env.object
        for k in range(len(obj.joints)):
            for fraction in (0.0, 0.5, 1.0):
                q = np.clip(0.0, obj.lower, obj.upper)
                q[k] = obj.lower[k] + fraction * (obj.upper[k] - obj.lower[k])
                obj.set_qpos(q)
                lo, hi = movable_links_box(env)
                assert np.all(lo > cube_lo) and np.all(hi < cube_hi), (name, obj.dof_names[k], fraction, lo, hi)
        assert env.object.scale == pytest.approx(fit_object(read_object_folder(root / name)).scale)


def test_a_continuous_knob_turns_past_its_reported_range(env, tmp_path):
    env.hulls = HullCache(tmp_path / "hulls")
    info = env.reset(folder=shared_partnet() / "101773", seed=0, dof_fraction=0.5)
    k = info.dof_names.index("joint_1")
    assert (info.dof_lower[k], info.dof_upper[k]) == pytest.approx(CONTINUOUS_RANGE)
    art = env.object.articulation
    q = art.get_qpos()
    q[k] = 4.0  # beyond pi: physics does not stop a continuous joint
    art.set_qpos(q)
    env.step(24)
    assert art.get_qpos()[k] == pytest.approx(4.0, abs=0.05)
    # success on a continuous joint: a turn of more than 30% of one full turn
    assert env.success(info.dof_initial)
    q = info.dof_initial.copy()
    q[k] += 0.25 * 2 * np.pi  # a quarter turn is not enough
    art.set_qpos(q)
    assert not env.success(info.dof_initial)


# -- a hand-made object: limits, categories, bad input ------------------------------------------------
def test_negative_zero_and_continuous_limits_are_reported(env, tmp_path):
    folder = make_object(tmp_path / "cab")
    env.hulls = HullCache(tmp_path / "hulls")
    info = env.reset(folder=folder, dof_fraction=0.0, jitter=False)
    assert info.object_id == "cab" and info.category == "storage_furniture"  # keyed by folder, not anno_id
    assert info.dof_names == ["joint_door", "joint_knob", "joint_slide"]
    np.testing.assert_allclose(info.dof_lower, [0.0, -np.pi, -0.3 * env.object.scale], atol=1e-6)
    np.testing.assert_allclose(info.dof_upper, [1.2, np.pi, 0.1 * env.object.scale], atol=1e-6)
    assert not np.signbit(info.dof_lower[0])  # "-0.0" reported as 0
    assert info.dof_initial[2] == pytest.approx(info.dof_lower[2], abs=1e-3)  # a negative lower limit is a reachable state


def test_category_names():
    assert category_name("StorageFurniture") == "storage_furniture"
    assert category_name("TrashCan") == "trash_can"
    assert category_name("USB") == "usb"
    assert category_name("WashingMachine") == "washing_machine"
    assert category_name("storage_furniture") == "storage_furniture"


def test_bad_folders_are_refused_with_the_file_and_reason_and_the_scene_stays(env, tmp_path):
    env.hulls = HullCache(tmp_path / "hulls")
    good = env.reset(folder=make_object(tmp_path / "good"), jitter=False)
    for case, (folder, words) in bad_folders(tmp_path).items():
        with pytest.raises(ObjectLoadError) as error:
            env.reset(folder=folder)
        message = str(error.value)
        assert all(w in message for w in words), (case, message)
        assert env.object.object_id == good.object_id, case  # the scene keeps the last good object


# -- convex decomposition -----------------------------------------------------------------------------
def test_a_u_handle_is_decomposed_once_into_the_cache_and_its_gap_stays_empty(env, tmp_path, caplog):
    assert solid_fraction(HANDLE) < 0.95 and solid_fraction(read_obj_box()) >= 0.95
    folder = make_object(tmp_path / "cab")
    before = sorted(p.relative_to(folder) for p in folder.rglob("*"))
    cache = HullCache(tmp_path / "hulls")

    # without the cache entry: one hull per mesh (a warning), the handle's hull fills the gap
    env.hulls = cache
    with caplog.at_level(logging.WARNING, logger="actaim2.sim.objects"):
        env.reset(folder=folder, jitter=False, dof_fraction=0.0)
    assert "prepare-objects" in caplog.text
    assert inside_any_shape(env.object.link("link_door"), gap_in_world(env))

    (report,) = prepare_objects(find_object_folders(folder), cache)
    outcomes = {r.mesh.name: (r.outcome, r.hulls) for r in report.reports}
    assert outcomes["handle.obj"][0] == "decomposed" and outcomes["handle.obj"][1] >= 3, outcomes
    assert outcomes["body.obj"] == ("convex", 1) and outcomes["door.obj"] == ("convex", 1)
    assert "knob.obj" not in outcomes and report.small == 1  # 4 cm at scale < 1: below MIN_DECOMPOSED_SIZE
    assert sorted(p.relative_to(folder) for p in folder.rglob("*")) == before  # nothing written into the dataset
    assert all(r.outcome == "cached" for r in prepare_objects([folder], cache)[0].reports)  # warm: nothing to do

    caplog.clear()
    other = SimEnv("panda", hull_cache=cache.root)  # a fresh load reads the hulls from the cache
    with caplog.at_level(logging.WARNING, logger="actaim2.sim.objects"):
        other.reset(folder=folder, jitter=False, dof_fraction=0.0)
    assert "prepare-objects" not in caplog.text
    door = other.object.link("link_door")
    assert len(door.collision_shapes) >= 4  # panel + the handle's pieces
    assert not inside_any_shape(door, gap_in_world(other))
    assert other.object.hulls == sum(len(link.collision_shapes) for link in other.object.links)


def read_obj_box() -> Mesh:
    return box((0, 0, 0), (0.3, 0.1, 0.02))


def gap_in_world(env: SimEnv) -> np.ndarray:
    T = env.object.link("link_door").entity_pose.to_transformation_matrix()
    return T[:3, :3] @ (BAR_GAP_POINT * env.object.scale) + T[:3, 3]


def test_obj_reader_handles_polygons_negative_indices_and_slashes(tmp_path):
    path = tmp_path / "quad.obj"
    path.write_text("# a quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1 4/1\nf -4 -3 -2\n")
    mesh = read_obj(path)
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [0, 1, 2]]
    path.write_text("v 0 0 0\nv 1 0 x\n")
    with pytest.raises(ValueError, match="line 2"):
        read_obj(path)


def test_workspace_cube_is_the_perception_rigs_cube():
    from actaim2.perception.config import load_perception_config

    for rig in ("ring5", "azure_kinect"):
        config = load_perception_config(rig)
        np.testing.assert_allclose(config.center, WORKSPACE_CENTER)
        assert config.half_extent == WORKSPACE_HALF_EXTENT
    assert 0.0 < WORKSPACE_MARGIN < WORKSPACE_HALF_EXTENT


def test_size_rule_shrinks_an_object_whose_drawer_would_leave_the_cube():
    info = read_object_folder(shared_partnet() / "22241")
    fit = fit_object(info)
    assert fit.scale < fit.category_scale and "shrunk" in fit.note
    assert fit_object(info, scale=0.3).scale == 0.3  # a given scale is kept
