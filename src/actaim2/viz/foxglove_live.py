"""The live view's Foxglove messages, built from the library's own data (no ROS here).

``viz_node`` turns what the graph publishes into these and logs them on the Foxglove SDK's
WebSocket server (protocol ``foxglove.websocket.v1``, what the Foxglove app connects to); the
committed layout ``docs/foxglove/actaim2_layout.json`` arranges the channels below in panels.

| channel | message | from |
|---|---|---|
| ``/fused_points`` | ``foxglove.PointCloud`` (xyz float32, rgba uint8) | /fused_points |
| ``/views/<view>`` | ``foxglove.RawImage`` rgb8, one per view | /ortho_views |
| ``/heatmaps/<view>`` | ``foxglove.RawImage`` rgb8: position probability | /policy/heatmaps |
| ``/keyposes`` | ``foxglove.SceneUpdate``: predicted and executed | /predict_keypose, /keypose |
| ``/keyposes/frames`` | ``foxglove.FrameTransforms``: the same, under ``world`` | as above |
| ``/tf`` | ``foxglove.FrameTransforms``: /tf_static and the links | /joint_states |
| ``/mode`` | JSON: the cluster in use and the cluster probabilities | /sample_mode |
| ``/episode`` | JSON: START / END, object, success | /episode |
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CubePrimitive,
    FrameTransform,
    FrameTransforms,
    PackedElementField,
    PackedElementFieldNumericType,
    PointCloud,
    Pose,
    Quaternion,
    RawImage,
    SceneEntity,
    SceneUpdate,
    TextPrimitive,
    Timestamp,
    Vector3,
)

from actaim2.keypose import PHASE_NAMES, Keypose
from actaim2.perception.ortho_views import rgb_mosaic

WORLD = "world"
POINT_STRIDE = 16  # x, y, z float32 at 0, 4, 8; red, green, blue, alpha uint8 at 12..15
FINGER_GAP_OPEN = 0.08  # m between the drawn fingers of an open gripper
FINGER_GAP_CLOSED = 0.01  # m, closed
PREDICTED = "predicted"  # the keypose /predict_keypose answered last: the one to be executed

MODE_SCHEMA = {
    "type": "object",
    "title": "actaim2 interaction mode",
    "properties": {
        "cluster": {"type": "integer", "description": "the cluster in use (-1: unknown)"},
        "probabilities": {"type": "array", "items": {"type": "number"},
                          "description": "the mode selector's cluster probabilities"},
        "requested": {"type": "integer", "description": "the cluster asked for (-1: drawn)"},
    },
}
EPISODE_SCHEMA = {
    "type": "object",
    "title": "actaim2 episode event",
    "properties": {
        "episode": {"type": "integer"},
        "event": {"type": "string", "enum": ["START", "END"]},
        "object_id": {"type": "string"},
        "success": {"type": "boolean"},
        "note": {"type": "string"},
    },
}


def timestamp(ns: int) -> Timestamp:
    return Timestamp(int(ns) // 1_000_000_000, int(ns) % 1_000_000_000)


def point_cloud(xyz: np.ndarray, rgb: np.ndarray | None, stamp_ns: int,
                frame_id: str = WORLD) -> PointCloud:
    """The finite points of ``xyz`` (N, 3) with their colours (N, 3 uint8; grey without)."""
    xyz = np.asarray(xyz, np.float32).reshape(-1, 3)
    keep = np.isfinite(xyz).all(axis=1)
    packed = np.empty(int(keep.sum()), np.dtype([("xyz", "<f4", 3), ("rgba", "u1", 4)]))
    packed["xyz"] = xyz[keep]
    packed["rgba"][:, :3] = 160 if rgb is None else np.asarray(rgb, np.uint8).reshape(-1, 3)[keep]
    packed["rgba"][:, 3] = 255
    f32, u8 = PackedElementFieldNumericType.Float32, PackedElementFieldNumericType.Uint8
    fields = [PackedElementField(name=n, offset=4 * i, type=f32) for i, n in enumerate("xyz")]
    fields += [PackedElementField(name=n, offset=12 + i, type=u8)
               for i, n in enumerate(("red", "green", "blue", "alpha"))]
    return PointCloud(timestamp=timestamp(stamp_ns), frame_id=frame_id, pose=_identity(),
                      point_stride=POINT_STRIDE, fields=fields, data=packed.tobytes())


def rgb_image(pixels: np.ndarray, stamp_ns: int, frame_id: str = WORLD) -> RawImage:
    """An (H, W, 3) uint8 array as an rgb8 image."""
    pixels = np.ascontiguousarray(pixels, np.uint8)
    height, width = pixels.shape[:2]
    return RawImage(timestamp=timestamp(stamp_ns), frame_id=frame_id, width=width,
                    height=height, encoding="rgb8", step=3 * width, data=pixels.tobytes())


def view_pictures(views: np.ndarray, channels: tuple[str, ...]) -> list[np.ndarray]:
    """Each view's colours (H, W, 3 uint8), empty pixels black; a ValueError when the views have
    no colour (channels r, g, b and occupancy)."""
    missing = [c for c in ("r", "g", "b", "occupancy") if c not in channels]
    if missing:
        raise ValueError(f"the views have no channel(s) {missing} to draw (channels {channels})")
    mosaic = rgb_mosaic(np.asarray(views, np.float32), tuple(channels))
    return np.split(mosaic, views.shape[0], axis=1)


def heatmap_pictures(probabilities: np.ndarray,
                     pictures: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """Each view's position probability (V, H, W), scaled to its own peak, in the ``inferno``
    colour map; blended over that view's colours when ``pictures`` of the same size are given."""
    probabilities = np.asarray(probabilities, np.float32)
    peak = probabilities.reshape(len(probabilities), -1).max(axis=1)[:, None, None]
    level = np.clip(probabilities / np.maximum(peak, 1e-12), 0.0, 1.0)
    coloured = _inferno()[np.round(level * 255).astype(np.int64)]
    if pictures is None or any(p.shape != c.shape for p, c in zip(pictures, coloured)):
        return list(coloured)
    weight = (0.35 + 0.65 * level)[..., None]
    return [(w * c + (1 - w) * p).round().astype(np.uint8)
            for w, c, p in zip(weight, coloured.astype(np.float32), pictures)]


def keypose_frame(keypose: Keypose, child: str, stamp_ns: int) -> FrameTransform:
    """The keypose's tcp pose as the frame ``child`` under ``world``."""
    return FrameTransform(timestamp=timestamp(stamp_ns), parent_frame_id=WORLD,
                          child_frame_id=child, translation=_vector(keypose.position),
                          rotation=_quaternion(keypose.quat_xyzw))


def keypose_label(keypose: Keypose, key: str) -> str:
    state = "closed" if keypose.gripper_closed else "open"
    return f"{key}: {PHASE_NAMES[keypose.phase]} {state}"


def keypose_entity(keypose: Keypose, key: str, stamp_ns: int) -> SceneEntity:
    """A gripper drawn at the keypose: two fingers as far apart as its state says, the approach
    axis (tcp z) as an arrow, and a label; the predicted one orange, executed ones blue."""
    colour = Color(r=1.0, g=0.55, b=0.0, a=1.0) if key == PREDICTED \
        else Color(r=0.2, g=0.5, b=1.0, a=0.8)
    gap = FINGER_GAP_CLOSED if keypose.gripper_closed else FINGER_GAP_OPEN
    rotation = _quaternion(keypose.quat_xyzw)
    world_from_tcp = quaternion_matrix(keypose.quat_xyzw)

    def at(offset: tuple[float, float, float], orientation: Quaternion = rotation) -> Pose:
        point = np.asarray(keypose.position, float) + world_from_tcp @ np.asarray(offset)
        return Pose(position=_vector(point), orientation=orientation)

    fingers = [CubePrimitive(pose=at((0.0, side * gap / 2, -0.025)),
                             size=Vector3(x=0.015, y=0.01, z=0.05), color=colour)
               for side in (-1.0, 1.0)]
    palm = CubePrimitive(pose=at((0.0, 0.0, -0.055)),
                         size=Vector3(x=0.02, y=gap + 0.02, z=0.01), color=colour)
    # the arrow primitive points along its own x axis: turned onto the tcp's z
    along_z = _quaternion(_turn_x_to_z(keypose.quat_xyzw))
    approach = ArrowPrimitive(pose=at((0.0, 0.0, -0.16), along_z),
                              shaft_length=0.08, shaft_diameter=0.006, head_length=0.02,
                              head_diameter=0.015, color=colour)
    text = TextPrimitive(pose=at((0.0, 0.0, -0.08)), billboard=True, font_size=12.0,
                         scale_invariant=True, color=colour, text=keypose_label(keypose, key))
    return SceneEntity(timestamp=timestamp(stamp_ns), frame_id=WORLD, id=f"keypose/{key}",
                       cubes=[*fingers, palm], arrows=[approach], texts=[text])


def keypose_scene(keyposes: dict[str, Keypose], stamp_ns: int) -> SceneUpdate:
    return SceneUpdate(entities=[keypose_entity(k, key, stamp_ns) for key, k in keyposes.items()])


def transform(parent: str, child: str, matrix: np.ndarray, stamp_ns: int) -> FrameTransform:
    """A 4x4 pose of ``child`` in ``parent`` as a FrameTransform."""
    return FrameTransform(timestamp=timestamp(stamp_ns), parent_frame_id=parent,
                          child_frame_id=child, translation=_vector(matrix[:3, 3]),
                          rotation=_quaternion(_matrix_quaternion(matrix[:3, :3])))


def frame_transforms(transforms: list[FrameTransform]) -> FrameTransforms:
    return FrameTransforms(transforms=transforms)


@dataclass(frozen=True)
class LinkTree:
    """The robot's links as a TF tree: every link's pose in its parent link at some joint angles,
    from the arm's Pinocchio model (``actaim2.control.model.RobotModel``; the root link itself is
    /tf_static's ``world -> root``)."""

    model: object  # RobotModel (imported by the caller: Pinocchio stays out of this import)

    def transforms(self, angles: np.ndarray, stamp_ns: int) -> list[FrameTransform]:
        import pinocchio as pin

        robot = self.model
        pin.forwardKinematics(robot.model, robot.data, robot.to_q(angles))
        pin.updateFramePlacements(robot.model, robot.data)
        frames = robot.model.frames
        out = []
        for index, frame in enumerate(frames):
            if frame.type != pin.FrameType.BODY:
                continue
            parent = _parent_link(frames, index, pin.FrameType.BODY)
            if parent <= 0:
                continue  # the root link: /tf_static places it
            relative = robot.data.oMf[parent].inverse() * robot.data.oMf[index]
            out.append(transform(frames[parent].name, frame.name, relative.homogeneous, stamp_ns))
        return out


def _parent_link(frames, index: int, body) -> int:
    """The nearest link frame above frame ``index`` (0 = none). A reduced model's locked joints
    can name themselves as their parent frame; their links then hang off the last link before
    them on the same joint (the Panda's fingers off ``panda_hand``)."""
    seen = {index}
    parent = frames[index].parentFrame
    while parent > 0 and frames[parent].type != body:
        if parent in seen:
            joint = frames[index].parentJoint
            return max((i for i in range(index) if frames[i].type == body
                        and frames[i].parentJoint == joint), default=0)
        seen.add(parent)
        parent = frames[parent].parentFrame
    return parent


def _inferno() -> np.ndarray:
    from matplotlib import colormaps

    return (colormaps["inferno"](np.linspace(0.0, 1.0, 256))[:, :3] * 255).round().astype(np.uint8)


def _identity() -> Pose:
    return Pose(position=Vector3(x=0.0, y=0.0, z=0.0),
                orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))


def _vector(v: np.ndarray) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def _quaternion(q: np.ndarray) -> Quaternion:
    return Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """The 3x3 rotation of a quaternion (x, y, z, w)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(np.asarray(q, float)).as_matrix()


def _matrix_quaternion(matrix: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(matrix, float)).as_quat()


def _turn_x_to_z(q: np.ndarray) -> np.ndarray:
    """The rotation ``q`` followed, in its own frame, by -90 deg about y (x onto z)."""
    from scipy.spatial.transform import Rotation

    turn = Rotation.from_euler("y", -90.0, degrees=True)
    return (Rotation.from_quat(np.asarray(q, float)) * turn).as_quat()
