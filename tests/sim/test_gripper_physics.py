"""Grippers as their controllers behave: gap width <-> finger joints, a bar wrapped by the fingers,
and a grip force limit that sets when a pulled part slips out."""
from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest

from actaim2.gripper import gripper_geometry
from actaim2.robots import load_robot_spec
from actaim2.rollout.expert import ExpertTask, ScriptedExpert
from actaim2.sim.env import SimEnv
from actaim2.sim.objects import catalog
from actaim2.sim.objects.dynamics import ObjectDynamics
from actaim2.sim.objects.physics_table import JointDynamics
from actaim2.sim.render_raycast import collision_shape_mesh

TABLE = ("table", 0)  # one drawer with a round bar handle on two standoffs


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    return SimEnv("panda", cache_dir=tmp_path_factory.mktemp("objects"))


@pytest.fixture(scope="module")
def expert(env):
    return ScriptedExpert(env)


def test_gap_width_and_finger_joint_convert_both_ways():
    panda = gripper_geometry(load_robot_spec("panda"))
    for q in (0.0, 0.013, 0.04):  # Panda: each finger slides half the gap
        assert panda.gap_from_joint(q) == pytest.approx(2 * q, abs=1e-4)
        assert panda.joint_from_gap(2 * q) == pytest.approx(q, abs=1e-4)
    assert panda.default_force == 70.0 and panda.effort_from_force(0.0) == pytest.approx(70.0)
    kinova = gripper_geometry(load_robot_spec("kinova_j2s6s200"))
    spec = load_robot_spec("kinova_j2s6s200")
    gaps = [kinova.gap_from_joint(q) for q in np.linspace(spec.gripper_open, spec.gripper_closed, 9)]
    assert np.all(np.diff(gaps) < 0) and 0.1 < gaps[0] < 0.14 and gaps[-1] < 0.015  # turning fingers: a curve
    for gap in (0.02, 0.05, 0.09):
        q = kinova.joint_from_gap(gap)
        assert kinova.gap_from_joint(q) == pytest.approx(gap, abs=1e-4)
        assert kinova.to_unit(gap, "finger_joint") == pytest.approx(q)
        assert kinova.from_unit(q, "finger_joint") == pytest.approx(gap, abs=1e-4)
        assert kinova.to_unit(gap, "gap_width") == kinova.from_unit(gap, "gap_width") == gap
    assert panda.joint_from_gap(-0.01) < 0.0  # narrower than closed: commanded past the stop, where it stalls
    with pytest.raises(ValueError, match="gripper position unit"):
        panda.to_unit(0.02, "millimetres")


def bar_of(env: SimEnv, handle) -> tuple[np.ndarray, np.ndarray, float]:
    """World centre, axis and radius of the round bar the handle annotation points at (read from
    the generator's model: in a folder with meshes the bar is a convex mesh piece)."""
    from scipy.spatial.transform import Rotation

    link = next(link for link in catalog.generate(*TABLE).links if link.name == handle.link)
    bar = min((s for s in link.shapes if s.kind == "cylinder"), key=lambda s: np.linalg.norm(np.subtract(s.xyz, handle.position)))
    T = env.object.link(handle.link).entity_pose.to_transformation_matrix()
    axis = T[:3, :3] @ Rotation.from_euler("xyz", bar.rpy).as_matrix()[:, 2]  # model cylinders run along local z
    return (T @ np.r_[bar.xyz, 1.0])[:3], axis, float(bar.size[0])


def occupied(links: list, points: np.ndarray) -> np.ndarray:
    """Whether each world point lies inside a collision shape of ``links``."""
    scene = o3d.t.geometry.RaycastingScene()
    for link in links:
        for shape in link.collision_shapes:
            vertices, triangles = collision_shape_mesh(shape)
            T = link.entity_pose.to_transformation_matrix() @ shape.local_pose.to_transformation_matrix()
            mesh = o3d.t.geometry.TriangleMesh(o3d.core.Tensor((vertices @ T[:3, :3].T + T[:3, 3]).astype(np.float32)),
                                               o3d.core.Tensor(triangles.astype(np.int32)))
            scene.add_triangles(mesh)
    return scene.compute_occupancy(o3d.core.Tensor(points.astype(np.float32))).numpy() > 0.5


@pytest.mark.parametrize("meshes", [False, True])
def test_a_bar_handle_is_wrapped(env, expert, tmp_path, meshes):
    """The space behind the bar is empty, the fingertips pass the bar and the pads close on the
    bar itself, around its whole diameter. With ``meshes`` every shape is its own OBJ (the
    real-folder path, one convex hull per file): the gap behind the bar stays empty there too."""
    folder = catalog.generate(*TABLE).write_folder(tmp_path / "table", meshes=meshes)
    env.reset(folder=folder, seed=0)
    handle = env.object.handles[0]
    assert handle.kind == "bar"
    centre, axis, radius = bar_of(env, handle)
    link = env.object.link(handle.link)
    T_link = link.entity_pose.to_transformation_matrix()
    towards_panel = T_link[:3, :3] @ np.asarray(handle.approach)
    # between the posts, from just behind the bar to just before the panel: nothing there
    gap = [centre + a * axis + d * towards_panel
           for a in np.linspace(-0.6, 0.6, 7) * (handle.span / 2 - 0.025)
           for d in np.linspace(radius + 0.003, handle.depth - 0.003, 6)]
    assert not occupied([link], np.array(gap)).any(), "the gap behind the bar is filled"
    plan = expert.plan(ExpertTask(handle.joint, +1))
    expert.reach(plan)
    fingers = {finger.entity.name for finger in env.robot.finger_links()}
    touches = [p.position for c in env.scene.get_contacts() if {c.bodies[0].entity.name, c.bodies[1].entity.name} & fingers
               for p in c.points if np.linalg.norm(p.impulse) > 0.0]
    assert touches, "the fingers do not touch the part"
    for point in touches:  # on the bar: a radius from its axis (not on a post, a slab or the panel)
        r = point - centre
        assert np.linalg.norm(r - (r @ axis) * axis) == pytest.approx(radius, abs=0.002)
    # the pads hold the whole diameter (PhysX lets 70 N press them ~1 mm into the bar each)
    assert 2 * radius - 0.003 < env.robot.gripper_gap() < 2 * radius + 0.0005
    in_tcp = np.linalg.inv(env.tcp_pose()) @ np.r_[centre, 1.0]
    assert np.abs(in_tcp[1:3]).max() < 0.004, in_tcp  # between the pads, at the fingertips' depth


def slip_force(env: SimEnv, expert: ScriptedExpert, grip_force: float, stiffness: float = 300.0) -> float:
    """Grasp the drawer's bar with ``grip_force``, tie the drawer to its closed stop with a spring
    of ``stiffness`` N/m, pull the hand back along the slide: the drawer follows until the spring
    pulls harder than friction at the pads holds; returns that force (stiffness x the furthest
    the drawer got)."""
    env.reset(*TABLE, seed=0, dof_fraction=0.0)
    obj = env.object
    plan = expert.plan(ExpertTask(obj.handles[0].joint, +1))
    expert.reach(plan)  # closes with the default force
    # a frictionless slide with a spring to the closed stop: the part is "blocked" by the spring
    obj.dynamics = ObjectDynamics(obj.articulation, obj.joints, [JointDynamics(0.0, 0.0)])
    joint = obj.joints[0]
    joint.set_drive_property(stiffness, 5.0, force_limit=1e4)
    joint.set_drive_target(float(obj.lower[0]))
    env.grip(closed=True, force=grip_force)  # the same grasp, now squeezing with grip_force
    furthest = 0.0
    motion = plan.manipulation
    for k in range(len(motion.joints) - 1):  # waypoints 1 cm apart
        expert.execute_motion(motion[k:k + 2], 0.03)
        furthest = max(furthest, float(env.object_dof()[0] - obj.lower[0]))
    assert env.object_dof()[0] - obj.lower[0] < furthest - 0.02, "the drawer never slipped out"
    return stiffness * furthest


def test_max_effort_sets_the_force_at_which_a_blocked_part_slips(env, expert):
    try:
        weak, strong = slip_force(env, expert, 12.0), slip_force(env, expert, 30.0)
    finally:
        env.sim.remove_object()  # its joint dynamics were replaced: the next reset loads it afresh
    # two pads, rubber on metal (friction ~1.1 combined): slip at about 2 x 1.1 x grip force
    assert weak == pytest.approx(2 * 1.1 * 12.0, rel=0.3) and strong == pytest.approx(2 * 1.1 * 30.0, rel=0.3)
    assert strong / weak == pytest.approx(30.0 / 12.0, rel=0.25)
