"""Camera rigs of the simulator: intrinsics, where each camera sits, and its ROS frame chain.

Two rigs:
  * ``ring5`` - five RGB-D cameras circling the articulated object, as in the paper
    (`/cameras/cam<k>/points`, frames ``cam<k>_link`` -> ``cam<k>_optical_frame``).
  * ``azure_kinect`` - one camera shaped like the real robot setup's Azure Kinect: NFOV depth
    intrinsics, topic ``/points2``, frames ``camera_base`` -> ``depth_camera_link`` exactly as
    the Azure Kinect ROS driver publishes them (depth_camera_link is an optical frame, tilted
    6 degrees down from camera_base, 1.8 mm above it), plus the device's separate colour
    camera (``rgb_camera_link``), which the driver registers into the depth camera's pixels.

Everything here is geometry: no SAPIEN, no rendering. A :class:`CameraSpec` carries the
*nominal* pose (what /tf_static publishes); renderers may be given a perturbed pose
(``actaim2.sim.sensor_noise``) to mimic a badly calibrated real camera.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.geometry import T_ENTITY_OPTICAL, depth_to_points

RIGS = ("ring5", "azure_kinect")


@dataclass(frozen=True)
class CameraSpec:
    """One pinhole depth camera: image size, intrinsics, valid range, pose and frames.

    ``T_world_optical`` maps points in the optical frame (x right, y down, z forward) to
    ``world``. ``tf_chain`` lists the /tf_static edges (parent, child, T_parent_child) from
    ``world`` to ``frame_id``; composing them gives ``T_world_optical``.
    """

    name: str
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    min_depth: float  # metres; closer returns are dropped, as a real sensor's operating range
    max_depth: float
    T_world_optical: np.ndarray
    frame_id: str
    topic: str
    tf_chain: tuple[tuple[str, str, np.ndarray], ...]
    # A separate colour camera rigidly attached to this one (the Azure Kinect's RGB camera), or
    # None: colour then comes from this camera's own view, perfectly registered.
    colour: "CameraSpec | None" = None
    # The documented (horizontal, vertical) field of view in degrees that the device's
    # undistorted cloud spans, when it differs from what fx, fy give (see :meth:`with_nominal_fov`).
    nominal_fov_deg: tuple[float, float] | None = None

    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def pixel_rays(self) -> np.ndarray:
        """(H, W, 3) ray directions in the optical frame with z = 1, through pixel centres: a depth of 1 everywhere
        back-projected (:func:`actaim2.geometry.depth_to_points`), so both render paths and the stored pictures share
        one pixel convention."""
        return depth_to_points(np.ones((self.height, self.width)), self.K)

    def with_pose(self, T_world_optical: np.ndarray) -> "CameraSpec":
        """The same camera rendered from another pose (frames and tf_chain stay nominal); an
        attached colour camera moves with it."""
        T_world_optical = np.asarray(T_world_optical, dtype=float)
        colour = None if self.colour is None else self.colour.with_pose(T_world_optical @ self.T_optical_colour)
        return replace(self, T_world_optical=T_world_optical, colour=colour)

    @property
    def T_optical_colour(self) -> np.ndarray:
        """Pose of the attached colour camera's optical frame in this camera's optical frame."""
        if self.colour is None:
            raise ValueError(f"camera '{self.name}' has no separate colour camera")
        return np.linalg.inv(self.T_world_optical) @ self.colour.T_world_optical

    def with_nominal_fov(self) -> "CameraSpec":
        """The pinhole on the same pixel grid whose image spans ``nominal_fov_deg`` edge to edge.

        A real lens bends the outer rays: the Azure Kinect's NFOV depth camera has fx ~ 504 px
        at 640 px wide (64.8 degrees through a pinhole) yet sees 75 degrees. This documented
        pinhole equivalent puts the outermost pixels on the outermost rays, so the cloud covers
        what the device's (undistorted) cloud covers, with non-square pixels.
        """
        if self.nominal_fov_deg is None:
            return self
        hfov, vfov = np.deg2rad(self.nominal_fov_deg)
        return replace(self, fx=0.5 * self.width / np.tan(hfov / 2.0), fy=0.5 * self.height / np.tan(vfov / 2.0),
                       cx=self.width / 2.0, cy=self.height / 2.0)


@dataclass(frozen=True)
class CameraFrame:
    """One rendered RGB-D frame, organized like the image (row v, column u).

    ``xyz`` is in the camera's optical frame, metres, NaN where there is no return (nothing
    hit, or outside the camera's depth range); ``segmentation`` holds the SAPIEN entity
    ``per_scene_id`` each pixel sees (0: nothing), which tests and data labelling use.
    """

    name: str
    xyz: np.ndarray  # (H, W, 3) float32
    rgb: np.ndarray  # (H, W, 3) uint8
    segmentation: np.ndarray  # (H, W) int32

    @property
    def depth(self) -> np.ndarray:
        """(H, W) distance along the optical axis (z), NaN for no return."""
        return self.xyz[..., 2]


def look_at_optical(eye: np.ndarray, target: np.ndarray, up: np.ndarray = np.array([0.0, 0.0, 1.0])) -> np.ndarray:
    """T_world_optical of a camera at ``eye`` whose optical axis (z) points at ``target``.

    Image "up" (-y) follows ``up`` as closely as possible; raises when the camera would look
    straight along ``up`` (the roll would be undefined).
    """
    eye, target, up = (np.asarray(a, dtype=float) for a in (eye, target, up))
    z = target - eye
    if np.linalg.norm(z) < 1e-9:
        raise ValueError("camera eye and target coincide")
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-6:
        raise ValueError("camera looks along the up vector: roll undefined")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, eye
    return T


def _intrinsics_from_fovy(width: int, height: int, fovy_deg: float) -> tuple[float, float, float, float]:
    f = 0.5 * height / np.tan(np.deg2rad(fovy_deg) / 2.0)
    return f, f, width / 2.0, height / 2.0


def ring5(
    target: np.ndarray,
    robot_xy: np.ndarray = np.zeros(2),
    distance: float = 1.2,
    elevation: float = 0.7,
    width: int = 320,
    height: int = 240,
    fovy_deg: float = 50.0,
) -> list[CameraSpec]:
    """Five cameras on a horizontal circle around ``target``, all looking at it.

    ``distance`` is the horizontal radius, ``elevation`` the height above the target. Azimuths
    are 36 + 72 k degrees from the direction target -> robot, so the two front cameras flank the
    robot instead of looking through it, and one camera sees the object from behind.
    The camera link frame is the ROS body convention (x forward, y left, z up), which is also
    SAPIEN's camera-entity frame; the optical frame hangs off it with a fixed rotation.
    """
    target = np.asarray(target, dtype=float)
    to_robot = np.asarray(robot_xy, dtype=float) - target[:2]
    base_azimuth = np.arctan2(to_robot[1], to_robot[0]) if np.linalg.norm(to_robot) > 1e-9 else np.pi
    fx, fy, cx, cy = _intrinsics_from_fovy(width, height, fovy_deg)
    cameras = []
    for k in range(5):
        azimuth = base_azimuth + np.deg2rad(36.0 + 72.0 * k)
        eye = target + np.array([distance * np.cos(azimuth), distance * np.sin(azimuth), elevation])
        T_world_optical = look_at_optical(eye, target)
        T_link_optical = T_ENTITY_OPTICAL
        T_world_link = T_world_optical @ np.linalg.inv(T_link_optical)
        name = f"cam{k}"
        cameras.append(
            CameraSpec(
                name=name,
                width=width,
                height=height,
                fx=fx,
                fy=fy,
                cx=cx,
                cy=cy,
                min_depth=0.05,
                max_depth=10.0,
                T_world_optical=T_world_optical,
                frame_id=f"{name}_optical_frame",
                topic=f"/cameras/{name}/points",
                tf_chain=(("world", f"{name}_link", T_world_link), (f"{name}_link", f"{name}_optical_frame", T_link_optical)),
            )
        )
    return cameras


def _tf2_set_euler(yaw: float, pitch: float, roll: float) -> Rotation:
    """tf2's ``Quaternion::setEuler(yaw, pitch, roll)``: yaw about Y, pitch about X, roll about Z."""
    return Rotation.from_euler("YXZ", [yaw, pitch, roll])


# camera_base -> depth_camera_link as published by the Azure Kinect ROS driver
# (K4ACalibrationTransformData::publishDepthToBaseTf): the depth camera is 1.8 mm above the
# base origin, turned into the ROS optical convention and pitched 6 degrees downward.
T_CAMERA_BASE_DEPTH = np.eye(4)
T_CAMERA_BASE_DEPTH[:3, :3] = (
    _tf2_set_euler(-np.pi / 2, np.pi, np.pi / 2) * _tf2_set_euler(0.0, np.deg2rad(-6.0), 0.0)
).as_matrix()
T_CAMERA_BASE_DEPTH[:3, 3] = [0.0, 0.0, 0.0018]

# Azure Kinect NFOV depth: a 640x576 crop of the 1 MP ToF sensor (2x2 binned: 320x288).
# Pinhole intrinsics of a typical factory calibration (fx = fy ~ 504 px unbinned; each device
# differs by a few pixels): only the image centre, since the lens distortion is not rendered.
# Azure Kinect DK hardware specification: NFOV 75 x 65 degrees; operating ranges 0.5-3.86 m
# unbinned, 0.5-5.46 m binned (for 15-95% reflectivity at 850 nm). Sensor realism renders the
# 75 x 65 degree pinhole equivalent instead (CameraSpec.with_nominal_fov).
AZURE_KINECT_NFOV_DEG = (75.0, 65.0)
AZURE_KINECT_NFOV = {
    "nfov_unbinned": dict(width=640, height=576, fx=504.0, fy=504.0, cx=320.0, cy=288.0, min_depth=0.5, max_depth=3.86),
    "nfov_binned": dict(width=320, height=288, fx=252.0, fy=252.0, cx=160.0, cy=144.0, min_depth=0.5, max_depth=5.46),
}

# The colour camera. Azure Kinect DK hardware specification: 90 x 59 degrees for the 16:9
# modes (720p and up); rendered at 640x360, half of 720p, to keep CPU rendering affordable (the
# field of view is what matters for registration). Its own lens distortion is not modelled.
AZURE_KINECT_COLOUR_FOV_DEG = (90.0, 59.0)
AZURE_KINECT_COLOUR_SIZE = (640, 360)
# depth_camera_link -> rgb_camera_link, as the driver publishes it from the factory calibration:
# the colour camera sits ~32 mm from the depth camera along the depth camera's x axis (Azure
# Kinect DK hardware specification: depth-to-colour baseline ~32 mm; typical factory extrinsics
# depth -> colour translate by about -32 mm in x), and the depth camera is tilted 6 degrees
# down from it, so the colour camera looks along camera_base's x axis.
AZURE_KINECT_BASELINE = 0.032
T_CAMERA_BASE_COLOUR = np.eye(4)
T_CAMERA_BASE_COLOUR[:3, :3] = _tf2_set_euler(-np.pi / 2, np.pi, np.pi / 2).as_matrix()
T_CAMERA_BASE_COLOUR[:3, 3] = T_CAMERA_BASE_DEPTH[:3, 3] + T_CAMERA_BASE_DEPTH[:3, 0] * AZURE_KINECT_BASELINE
T_DEPTH_COLOUR = np.linalg.inv(T_CAMERA_BASE_DEPTH) @ T_CAMERA_BASE_COLOUR


def _azure_colour_camera(T_world_depth: np.ndarray, tf_chain: tuple) -> CameraSpec:
    width, height = AZURE_KINECT_COLOUR_SIZE
    hfov, vfov = np.deg2rad(AZURE_KINECT_COLOUR_FOV_DEG)
    return CameraSpec(
        name="azure_kinect_rgb", width=width, height=height,
        fx=0.5 * width / np.tan(hfov / 2.0), fy=0.5 * height / np.tan(vfov / 2.0), cx=width / 2.0, cy=height / 2.0,
        min_depth=0.05, max_depth=10.0,
        T_world_optical=T_world_depth @ T_DEPTH_COLOUR, frame_id="rgb_camera_link", topic="",
        tf_chain=tf_chain + (("depth_camera_link", "rgb_camera_link", T_DEPTH_COLOUR),),
    )


def azure_kinect(
    target: np.ndarray,
    robot_xy: np.ndarray = np.zeros(2),
    distance: float = 1.3,
    elevation: float = 0.6,
    azimuth_deg: float = 60.0,
    mode: str = "nfov_binned",
) -> list[CameraSpec]:
    """One Azure Kinect on a tripod, ``distance`` (horizontal) from ``target``, looking at it.

    ``azimuth_deg`` is measured from the direction target -> robot, so the default views the
    object from the robot's side without looking through the arm, like the paper's
    third-person real setup. ``camera_base`` is placed so that the depth camera's optical
    axis passes through the target (the 6-degree tilt is compensated).
    """
    if mode not in AZURE_KINECT_NFOV:
        raise ValueError(f"unknown Azure Kinect mode '{mode}': use one of {list(AZURE_KINECT_NFOV)}")
    target = np.asarray(target, dtype=float)
    to_robot = np.asarray(robot_xy, dtype=float) - target[:2]
    base_azimuth = np.arctan2(to_robot[1], to_robot[0]) if np.linalg.norm(to_robot) > 1e-9 else np.pi
    azimuth = base_azimuth + np.deg2rad(azimuth_deg)
    eye = target + np.array([distance * np.cos(azimuth), distance * np.sin(azimuth), elevation])
    T_world_optical = look_at_optical(eye, target)
    T_world_base = T_world_optical @ np.linalg.inv(T_CAMERA_BASE_DEPTH)
    tf_chain = (("world", "camera_base", T_world_base), ("camera_base", "depth_camera_link", T_CAMERA_BASE_DEPTH))
    return [
        CameraSpec(
            name="azure_kinect",
            T_world_optical=T_world_optical,
            frame_id="depth_camera_link",
            topic="/points2",
            tf_chain=tf_chain,
            colour=_azure_colour_camera(T_world_optical, tf_chain),
            nominal_fov_deg=AZURE_KINECT_NFOV_DEG,
            **AZURE_KINECT_NFOV[mode],
        )
    ]


def make_rig(
    rig: str, target: np.ndarray, robot_xy: np.ndarray = np.zeros(2), width: int = 0, height: int = 0
) -> list[CameraSpec]:
    """A rig by name; ``width``/``height`` of 0 keep the rig's default resolution.

    The Azure Kinect only has its two NFOV depth resolutions: 320x288 (binned, the default)
    and 640x576 (unbinned); the size selects the mode.
    """
    if rig == "ring5":
        size = {}
        if width > 0:
            size["width"] = width
        if height > 0:
            size["height"] = height
        return ring5(target, robot_xy, **size)
    if rig == "azure_kinect":
        if (width, height) == (0, 0):
            return azure_kinect(target, robot_xy)
        for mode, intrinsics in AZURE_KINECT_NFOV.items():
            if (intrinsics["width"], intrinsics["height"]) == (width, height):
                return azure_kinect(target, robot_xy, mode=mode)
        sizes = [f"{m['width']}x{m['height']}" for m in AZURE_KINECT_NFOV.values()]
        raise ValueError(f"the Azure Kinect NFOV depth camera is {' or '.join(sizes)}, not {width}x{height}")
    raise ValueError(f"unknown camera rig '{rig}': use one of {RIGS}")
