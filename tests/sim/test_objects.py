"""The articulated-object library: catalogue, splits, and every instance of every category built in SAPIEN."""
from __future__ import annotations

import json

import numpy as np
import pytest
import sapien

from actaim2.sim.objects import catalog
from actaim2.sim.objects.loader import ObjectLoadError, aabb, load_object
from actaim2.sim.objects.model import read_handles, read_meta


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("objects")


@pytest.fixture(scope="module")
def scene():
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(1.0 / 240.0)
    return scene


def test_splits_follow_the_paper():
    seen, unseen = catalog.split_instances("train_seen"), catalog.split_instances("train_unseen_instance")
    heldout = catalog.split_instances("heldout_category")
    train_categories = {"faucet", "table", "storage_furniture", "door", "refrigerator", "switch"}
    assert {c for c, _ in seen} == {c for c, _ in unseen} == train_categories
    assert {c for c, _ in heldout} == {"window", "box", "safe"}
    for split in (seen, unseen, heldout):
        for category in {c for c, _ in split}:
            assert sum(c == category for c, _ in split) >= 8
    assert not set(seen) & set(unseen), "an instance is both seen and unseen"
    for category in train_categories:
        assert len(catalog.category_instances(category)) >= 16
    assert catalog.split_instances("real_robot") == [("three_drawer_shelf", 0)]
    with pytest.raises(ValueError, match="unknown split"):
        catalog.split_instances("test")


def test_generation_is_deterministic_and_instances_differ():
    a, b = catalog.generate("storage_furniture", 3), catalog.generate("storage_furniture", 3)
    assert a.to_urdf() == b.to_urdf()
    assert len({catalog.generate("door", i).to_urdf() for i in range(8)}) == 8
    with pytest.raises(ValueError, match="unknown object category"):
        catalog.generate("teapot", 0)


@pytest.mark.parametrize("category", catalog.list_categories())
def test_every_instance_builds(category, cache, scene):
    """Each instance loads as one articulation with finite limits, a handle on every movable part,
    the half-open state inside its limits, and the object standing on the floor in front of the robot."""
    kinds = set()
    for instance in catalog.category_instances(category):
        folder = catalog.object_folder(category, instance, cache)
        obj = load_object(scene, folder)
        try:
            assert obj.category == category and obj.object_id == catalog.object_id(category, instance)
            assert len(obj.joints) >= 1
            assert np.all(obj.upper > obj.lower)
            assert {h.joint for h in obj.handles} == set(obj.dof_names)
            kinds |= {j.type for j in obj.joints}
            obj.set_qpos((obj.lower + obj.upper) / 2)
            np.testing.assert_allclose(obj.qpos(), (obj.lower + obj.upper) / 2, atol=1e-5)
            lo, hi = aabb(obj.articulation)
            assert abs(lo[2]) < 0.02, "object not on the floor"
            assert 0.25 < lo[0] and hi[0] < 1.4 and abs(lo[1] + hi[1]) < 0.2
            for h in obj.handles:  # every handle within the arm's reach
                T = obj.link(h.link).entity_pose.to_transformation_matrix() @ h.tcp_in_link()
                assert 0.25 < np.linalg.norm(T[:2, 3]) < 0.85 and 0.1 < T[2, 3] < 0.9, (obj.object_id, h)
            assert read_meta(folder)["model_cat"] == category
        finally:
            scene.remove_articulation(obj.articulation)
    if category in ("storage_furniture", "switch", "window", "door", "table", "refrigerator", "box"):
        assert kinds == {"prismatic", "revolute_unwrapped"}, f"{category} should mix slides and hinges"


def test_every_category_has_four_structures_and_every_handle_kind_is_built():
    from actaim2.sim.objects.categories import LAYOUTS
    from actaim2.sim.objects.parts import HANDLE_KINDS

    kinds = set()
    for category in catalog.list_categories():
        models = [catalog.generate(category, i) for i in catalog.category_instances(category)]
        layouts = {m.params["layout"] for m in models}
        signatures = {catalog.structure_signature(m) for m in models}
        if category != "three_drawer_shelf":  # the real robot's one object
            assert len(layouts) >= 4 and layouts == set(LAYOUTS[category]), (category, layouts)
            assert len(signatures) >= 4, category
        kinds |= {h.kind for m in models for h in m.handles}
    assert set(HANDLE_KINDS) <= kinds, set(HANDLE_KINDS) - kinds


@pytest.mark.parametrize("hinge", ["left", "right"])
def test_a_recessed_lip_is_a_pocket_cut_into_a_whole_panel(hinge):
    """The panel's boxes tile it without overlap except for the pocket, on either hinge side."""
    from actaim2.sim.objects.parts import POCKET_WIDTH, Builder, Palette, add_hinged_panel

    rng = np.random.default_rng(0)
    b = Builder("test_door", "door")
    W, H, t = 0.4, 0.8, 0.035
    link = add_hinged_panel(b, "door", "base", (-W / 2, W / 2, 0.0, H), 0.0, t, hinge, 1.4, "recessed", H / 2, rng,
                            Palette.sample(rng))
    handle = b.handles[0]
    lo = np.min([np.subtract(s.xyz, np.divide(s.size, 2)) for s in link.shapes], axis=0)
    hi = np.max([np.add(s.xyz, np.divide(s.size, 2)) for s in link.shapes], axis=0)
    np.testing.assert_allclose(hi - lo, [t, W, H], atol=1e-9)
    pocket = POCKET_WIDTH * handle.span * min(0.03, t - 0.008)
    assert sum(np.prod(s.size) for s in link.shapes) == pytest.approx(t * W * H - pocket, rel=1e-9)
    lip_side = 1.0 if hinge == "right" else -1.0  # the free edge: +y of a right-hinged panel's link frame
    assert handle.position[1] * lip_side > W - 0.02 and handle.position[0] > -t  # on the lip, inside the panel


def test_no_two_instances_are_near_duplicates_and_the_rule_catches_one():
    for category in catalog.list_categories():
        models = [catalog.generate(category, i) for i in catalog.category_instances(category)]
        for a in range(len(models)):
            for b in range(a):
                assert not catalog.near_duplicates(models[a], models[b]), (models[a].object_id, models[b].object_id)
    # the rule: the same structure with sizes a little apart is a near-duplicate, another structure never is
    model = catalog.generate("door", 0)
    close = catalog.generate("door", 0)
    close.params["dims"] = {k: min(1.0, v + 0.1) for k, v in close.params["dims"].items()}
    assert catalog.size_distance(model, close) == pytest.approx(0.1, abs=0.02) and catalog.near_duplicates(model, close)
    apart = catalog.generate("door", 0)
    apart.params["dims"] = {k: v + (0.2 if v < 0.5 else -0.2) for k, v in apart.params["dims"].items()}
    assert catalog.size_distance(model, apart) == pytest.approx(0.2) and not catalog.near_duplicates(model, apart)
    other = catalog.generate("door", 1)  # another layout
    other.params["dims"] = dict(model.params["dims"])
    assert catalog.structure_signature(other) != catalog.structure_signature(model) and not catalog.near_duplicates(model, other)


def test_some_objects_have_several_movable_parts(cache):
    counts = {c: max(len(catalog.generate(c, i).movable_joints()) for i in catalog.category_instances(c)) for c in catalog.list_categories()}
    assert counts["storage_furniture"] >= 2 and counts["table"] >= 2 and counts["refrigerator"] >= 2
    assert counts["three_drawer_shelf"] == 3


def test_partnet_folder_with_meshes_loads_through_the_same_path(tmp_path, scene):
    """A folder in PartNet-Mobility layout with OBJ meshes (as real PartNet objects have) loads like a generated one."""
    model = catalog.generate("storage_furniture", 2)
    folder = model.write_folder(tmp_path / "partnet_like", meshes=True)
    assert (folder / "mobility.urdf").is_file() and any((folder / "textured_objs").glob("*.obj"))
    assert "textured_objs/" in (folder / "mobility.urdf").read_text()
    assert (folder / "semantics.txt").read_text().split("\n")[0].split()[1:] == ["slider", "drawer"]
    obj = load_object(scene, folder)
    try:
        assert obj.dof_names == [j.name for j in model.movable_joints()]
        np.testing.assert_allclose(obj.upper, [j.upper for j in model.movable_joints()], rtol=1e-5)
        shapes = [s for link in obj.links for s in link.collision_shapes]
        assert shapes and all(isinstance(s, sapien.physx.PhysxCollisionShapeConvexMesh) for s in shapes)
        assert read_handles(folder) == model.handles
    finally:
        scene.remove_articulation(obj.articulation)


def test_folder_without_annotations_loads_and_bad_folders_are_refused(tmp_path, scene):
    folder = catalog.generate("safe", 1).write_folder(tmp_path / "plain")
    (folder / "handles.json").unlink()
    (folder / "meta.json").unlink()
    obj = load_object(scene, folder, front_distance=0.6)
    try:
        assert obj.handles == [] and obj.category == "unknown" and len(obj.joints) == 1
        assert aabb(obj.articulation)[0][0] == pytest.approx(0.6, abs=1e-3)
    finally:
        scene.remove_articulation(obj.articulation)
    with pytest.raises(ObjectLoadError, match="mobility.urdf"):
        load_object(scene, tmp_path)


def test_a_folder_another_process_finished_meanwhile_is_kept_and_an_old_format_is_replaced(tmp_path, monkeypatch):
    """Two collection workers start the same uncached object: the second to finish generating
    must not delete the first one's folder, which the first may be loading already."""
    real_generate, marker = catalog.generate, "loaded_by_the_first_process"

    def generate_while_another_process_finishes(category: str, instance: int):
        monkeypatch.setattr(catalog, "generate", real_generate)
        first = catalog.object_folder(category, instance, tmp_path)  # the other process, start to end
        (first / marker).write_text("")
        return real_generate(category, instance)

    monkeypatch.setattr(catalog, "generate", generate_while_another_process_finishes)
    folder = catalog.object_folder("faucet", 0, tmp_path)
    assert (folder / marker).is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == [folder.name]  # the loser's copy is gone

    meta = read_meta(folder)
    (folder / "meta.json").write_text(json.dumps({**meta, "format_version": meta["format_version"] - 1}))
    assert catalog.object_folder("faucet", 0, tmp_path) == folder
    assert read_meta(folder) == meta and not (folder / marker).exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [folder.name]
