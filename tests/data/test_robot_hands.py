"""The samplers' box model of each preset's open hand against the preset's URDF collision meshes."""
from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from actaim2.robots import RobotSpec, load_robot_spec, movable_gripper_urdf

HAND_LINKS = {
    "panda": ("panda_hand", "panda_leftfinger", "panda_rightfinger"),
    "kinova_j2s6s200": ("j2s6s200_link_6", "j2s6s200_link_finger_1", "j2s6s200_link_finger_tip_1",
                        "j2s6s200_link_finger_2", "j2s6s200_link_finger_tip_2"),
}
MARGIN = 0.01  # m the boxes may leave out: Panda's fingertip collision boxes reach 9.5 mm past its tcp


def hand_vertices(spec: RobotSpec) -> dict[str, np.ndarray]:
    """Collision-mesh vertices of the hand links, gripper open, in the canonical tcp frame."""
    urdf = str(movable_gripper_urdf(spec))
    model = pin.buildModelFromUrdf(urdf)
    geometry = pin.buildGeomFromUrdf(model, urdf, pin.GeometryType.COLLISION)
    q = pin.neutral(model)
    for joint in spec.gripper_joints:
        q[model.joints[model.getJointId(joint)].idx_q] = spec.gripper_open
    data, gdata = model.createData(), pin.GeometryData(geometry)
    pin.framesForwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, geometry, gdata)
    tcp_inv = np.linalg.inv(data.oMf[model.getFrameId(spec.flange_frame)].homogeneous @ spec.T_flange_tcp)
    out: dict[str, list[np.ndarray]] = {}
    for i, obj in enumerate(geometry.geometryObjects):
        link = model.frames[obj.parentFrame].name
        if link not in HAND_LINKS[spec.name]:
            continue
        shape = obj.geometry
        if hasattr(shape, "halfSide"):  # a box primitive (Panda's fingers)
            v = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) * shape.halfSide
        else:
            v = np.array([shape.vertices(k) for k in range(shape.num_vertices)])
        T = tcp_inv @ gdata.oMg[i].homogeneous
        out.setdefault(link, []).append(v @ T[:3, :3].T + T[:3, 3])
    return {link: np.concatenate(v) for link, v in out.items()}


def _inside(points: np.ndarray, box: tuple[np.ndarray, np.ndarray], margin: float) -> np.ndarray:
    return np.all((points >= box[0] - margin) & (points <= box[1] + margin), axis=1)


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # coal's BVHModel.vertices(i)
@pytest.mark.parametrize("name", ["panda", "kinova_j2s6s200"])
def test_hand_boxes_fit_the_urdf_meshes(name):
    spec = load_robot_spec(name)
    hand = spec.hand
    vertices = hand_vertices(spec)
    assert set(vertices) == set(HAND_LINKS[name])
    every = np.concatenate(list(vertices.values()))
    extent = hand.hand_extent()
    # Nothing of the hand sticks out of the region the collision check looks at ...
    assert np.all(np.abs(every[:, :2]) <= extent[:2] + MARGIN)
    assert np.all((every[:, 2] >= -extent[2] - MARGIN) & (every[:, 2] <= MARGIN))
    # ... the space between the open fingers is free (what lies there gets grasped) ...
    assert not _inside(every, hand.closing_region(), -0.002).any()
    # ... and the finger links lie in the boxes.
    fingers = np.concatenate([v for link, v in vertices.items() if "finger" in link])
    in_boxes = np.any([_inside(fingers, box, MARGIN) for box in hand.boxes().values()], axis=0)
    assert in_boxes.mean() >= 0.95, f"{name}: {in_boxes.mean():.1%} of finger vertices in the boxes"


@pytest.mark.parametrize("name", ["panda", "kinova_j2s6s200"])
def test_reach_shell_is_inside_what_the_arm_reaches(name):
    """The shell is centred on the second joint (the shoulder) and lies within the arm's reach."""
    from actaim2.control.model import RobotModel

    spec = load_robot_spec(name)
    robot = RobotModel(spec)
    pin.forwardKinematics(robot.model, robot.data, robot.to_q(spec.home))
    np.testing.assert_allclose(spec.reach.center, robot.data.oMi[2].translation, atol=0.002)
    rng = np.random.default_rng(0)
    lower = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    farthest = max(np.linalg.norm(robot.fk(rng.uniform(lower, upper))[:3, 3] - spec.reach.center) for _ in range(3000))
    assert 0.8 * farthest < spec.reach.max < 0.9 * farthest
