"""A camera's extrinsic refined from the robot itself, before the robot is filtered out of its cloud.

Why: the self-filter removes points inside the robot's collision geometry grown by a 10 mm margin,
posed through the camera's extrinsic (``/tf_static``, a hand-eye calibration). A calibration off by
5 mm / 0.5 deg, or a depth camera's systematic range error of up to 11 mm, puts the arm's points
outside that margin and the arm stays in the robot-hidden observations. The robot is in the cloud,
and where it stands is known (the robot model and ``/joint_states`` at the cloud's stamp), so its
visible surface can be registered to the cloud and the extrinsic corrected by that registration.

How: points are sampled on the robot's visual meshes (the surface a camera sees; URDF loaded by
Pinocchio, posed by its forward kinematics: :class:`RobotSurface`). The cloud's points near the
posed surface (world frame, through the given extrinsic) are registered to it by Open3D's
point-to-plane ICP, coarse to fine with a robust (Tukey) loss so that a handle in the gripper or
the floor under the base does not pull the fit; each point's nearest surface point on the camera's
side of a link is its correspondence, so the hidden sides of the links do not matter. The
correction C (world frame, C x ~ surface) gives the refined extrinsic T' = C T.

A refinement is refused, and the extrinsic kept, when the fit says it cannot be trusted
(:class:`RefinementLimits`): too few arm points in view, too small a share of them fitted
(fitness) or too large a residual (RMSE), or a correction beyond the bound a hand-eye calibration
can be off by (which ICP reaches only by fitting the arm to something else). The reason is said.

A systematic range error (a time-of-flight camera's shift or scale along the rays) is taken up by the
correction too: at the arm's depth a scale along the rays cannot be told from a camera translation, so
no separate depth scale is fitted (docs/decisions.md); the refined extrinsic removes the arm where a
calibrated one would not.

It reads only what a real recording holds: the cloud, its extrinsic, the joint positions at its
stamp and the robot model; never a simulator's true camera pose.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable

import numpy as np
import open3d as o3d
import pinocchio as pin
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from actaim2.geometry import transform_points
from actaim2.perception.self_filter import set_configuration
from actaim2.robots import RobotSpec

SURFACE_SPACING = 0.004  # m: mean distance between the surface samples, finer than the depth noise
EDGE_JUMP = 0.02  # a depth step to a neighbour pixel larger than this share of the depth is a silhouette
SMOOTHING_RADIUS = 2  # pixels: the depth averaged over a 5 x 5 window before the fit


@dataclass(frozen=True)
class RefinementLimits:
    """When a refinement is accepted, and the ICP schedule that makes it."""

    crop: float = 0.05  # m: cloud points this close to the posed surface take part (above the calibration's error)
    distances: tuple[float, ...] = (0.04, 0.02, 0.012)  # m: correspondence distance of each ICP stage
    iterations: int = 30  # per stage
    min_points: int = 300  # arm points in view needed for a fit
    min_fitness: float = 0.5  # share of those points within the last stage's distance after the fit
    max_rmse: float = 0.007  # m: their RMS point-to-point distance after the fit (the depth noise is ~5 mm at 1.2 m)
    max_translation: float = 0.03  # m: largest correction of the camera's position accepted
    max_rotation_deg: float = 3.0  # largest correction of its orientation accepted


@dataclass(frozen=True)
class Refinement:
    """The outcome for one cloud: the extrinsic to use and how the fit went."""

    accepted: bool
    reason: str  # why refused; empty when accepted
    T_world_optical: np.ndarray  # refined when accepted, else the given one
    correction: np.ndarray  # 4x4 world-frame C with T' = C T (identity when refused)
    translation: float  # m: how far the correction moves the camera (that of the fit, refused or not)
    rotation_deg: float  # how far it turns it
    fitness: float
    rmse: float  # m
    points: int  # arm points the fit used

    def to_json(self) -> dict:
        return {"accepted": self.accepted, "reason": self.reason, "T_world_optical": self.T_world_optical.tolist(),
                "translation_m": round(self.translation, 6), "rotation_deg": round(self.rotation_deg, 5),
                "fitness": round(self.fitness, 4), "rmse_m": round(self.rmse, 6), "points": self.points}


@dataclass
class _Mesh:
    joint: int
    placement: np.ndarray  # 4x4 mesh frame in the joint frame
    points: np.ndarray  # (S, 3) surface samples, mesh frame
    normals: np.ndarray  # (S, 3) unit face normals there


def _mesh_samples(geometry, spacing: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Area-uniform samples of a triangle mesh (coal BVH) with their face normals, ~one per ``spacing``^2."""
    vertices = np.asarray(geometry.vertices(), dtype=float)
    triangles = np.array([[t[0], t[1], t[2]] for t in map(geometry.tri_indices, range(geometry.num_tris))], dtype=np.int64)
    a, b, c = (vertices[triangles[:, i]] for i in range(3))
    cross = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    n = max(1, int(area.sum() / spacing**2))
    face = rng.choice(len(triangles), n, p=area / area.sum())
    u, v = rng.random((2, n))
    flip = u + v > 1.0
    u[flip], v[flip] = 1.0 - u[flip], 1.0 - v[flip]
    points = a[face] + u[:, None] * (b - a)[face] + v[:, None] * (c - a)[face]
    normals = cross[face] / np.maximum(2.0 * area[face], 1e-12)[:, None]
    return points, normals


class RobotSurface:
    """Points on the robot's visual meshes, posed at given joint positions (world frame)."""

    def __init__(self, spec: RobotSpec, spacing: float = SURFACE_SPACING, seed: int = 0) -> None:
        self.model, geometry = pin.buildModelsFromUrdf(
            str(spec.urdf_path), package_dirs=[str(p) for p in spec.package_dirs], geometry_types=pin.GeometryType.VISUAL)
        self._data = self.model.createData()
        rng = np.random.default_rng(seed)
        self._meshes = []
        for obj in geometry.geometryObjects:
            if not hasattr(obj.geometry, "tri_indices"):
                continue  # a primitive without a mesh: no camera-facing samples to add
            points, normals = _mesh_samples(obj.geometry, spacing, rng)
            self._meshes.append(_Mesh(obj.parentJoint, obj.placement.homogeneous, points * obj.meshScale, normals))
        if not self._meshes:
            raise ValueError(f"{spec.name}: the URDF has no visual meshes to register a cloud to")

    def posed(self, joint_positions: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """(points (N, 3), normals (N, 3)) in the world frame with the robot at ``joint_positions``."""
        q = pin.neutral(self.model)
        set_configuration(self.model, q, joint_positions)
        pin.forwardKinematics(self.model, self._data, q)
        points, normals = [], []
        for mesh in self._meshes:
            T = self._data.oMi[mesh.joint].homogeneous @ mesh.placement
            points.append(mesh.points @ T[:3, :3].T + T[:3, 3])
            normals.append(mesh.normals @ T[:3, :3].T)
        return np.concatenate(points), np.concatenate(normals)


def _cloud(points: np.ndarray, normals: np.ndarray | None = None) -> o3d.geometry.PointCloud:
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64)))
    if normals is not None:
        cloud.normals = o3d.utility.Vector3dVector(np.ascontiguousarray(normals, dtype=np.float64))
    return cloud


def _camera_motion(T_before: np.ndarray, T_after: np.ndarray) -> tuple[float, float]:
    """(metres, degrees) between two camera poses."""
    delta = np.linalg.inv(T_before) @ T_after
    return float(np.linalg.norm(delta[:3, 3])), float(np.rad2deg(Rotation.from_matrix(delta[:3, :3]).magnitude()))


def _icp(source: o3d.geometry.PointCloud, target: o3d.geometry.PointCloud, limits: RefinementLimits,
         init: np.ndarray) -> o3d.pipelines.registration.RegistrationResult:
    """Point-to-plane ICP coarse to fine, Tukey loss at each stage's distance."""
    reg = o3d.pipelines.registration
    result, T = None, init
    for distance in limits.distances:
        estimation = reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=distance))
        result = reg.registration_icp(source, target, distance, T, estimation,
                                      reg.ICPConvergenceCriteria(max_iteration=limits.iterations))
        T = result.transformation
    return result


def front_pixels(xyz: np.ndarray, jump: float = EDGE_JUMP) -> np.ndarray:
    """(H, W) True where an organized cloud's pixel returned and no 4-neighbour lies nearer than it by more than
    ``jump`` times its depth: surfaces with their front silhouettes, without what a foreground edge leaves behind
    it (the flying pixels a time-of-flight camera mixes from the two surfaces, biased away from the camera)."""
    z = np.where(np.isfinite(xyz).all(axis=-1), xyz[..., 2], np.nan)
    padded = np.pad(z, 1, constant_values=np.nan)
    neighbours = np.stack([padded[:-2, 1:-1], padded[2:, 1:-1], padded[1:-1, :-2], padded[1:-1, 2:]])
    with np.errstate(invalid="ignore"):
        return np.isfinite(z) & ~(neighbours < z - jump * z).any(axis=0)


def smoothed(xyz: np.ndarray, radius: int = SMOOTHING_RADIUS, jump: float = EDGE_JUMP) -> np.ndarray:
    """The organized cloud with each pixel moved along its ray to the mean depth of the pixels of its
    (2 radius + 1)^2 window on the same surface (depth within ``jump`` times its own).

    Why: the range noise (about 5 mm at 1.2 m) scatters points along the rays, across the arm's round links
    at a slant to their surface, which biases the fit by millimetres (docs/decisions.md); averaging 25 pixels
    divides the noise by five while leaving surfaces apart."""
    z = np.where(np.isfinite(xyz).all(axis=-1), xyz[..., 2], np.nan)
    h, w = z.shape
    padded = np.pad(z, radius, constant_values=np.nan)
    total, count = np.zeros_like(z), np.zeros_like(z)
    for dy in range(2 * radius + 1):
        for dx in range(2 * radius + 1):
            other = padded[dy:dy + h, dx:dx + w]
            with np.errstate(invalid="ignore"):
                same = np.abs(other - z) <= jump * z
            total += np.where(same, other, 0.0)
            count += same
    with np.errstate(invalid="ignore", divide="ignore"):
        return xyz * (total / count / z)[..., None]


def refine_extrinsic(xyz: np.ndarray, T_world_optical: np.ndarray, surface: tuple[np.ndarray, np.ndarray],
                     limits: RefinementLimits = RefinementLimits()) -> Refinement:
    """Refine ``T_world_optical`` by registering the robot's posed ``surface`` (points, normals; world frame,
    :meth:`RobotSurface.posed` at the cloud's stamp) to the organized cloud ``xyz`` ((H, W, 3) camera frame,
    NaN = no return; its :func:`front_pixels` alone, :func:`smoothed`); a refused :class:`Refinement` (with the
    reason) keeps the given extrinsic."""
    target_points, target_normals = surface
    points = smoothed(np.asarray(xyz, dtype=float))[front_pixels(xyz)]
    gap, _ = cKDTree(target_points).query(transform_points(T_world_optical, points), distance_upper_bound=limits.crop)
    arm = points[np.isfinite(gap)]

    def refused(reason: str, translation: float = 0.0, rotation: float = 0.0, fitness: float = 0.0,
                rmse: float = 0.0) -> Refinement:
        return Refinement(False, reason, np.asarray(T_world_optical, float), np.eye(4), translation, rotation, fitness,
                          rmse, len(arm))

    if len(arm) < limits.min_points:
        return refused(f"{len(arm)} cloud points within {limits.crop * 100:.0f} cm of the robot, fewer than "
                       f"{limits.min_points}: too little of the arm in view")
    T = np.asarray(T_world_optical, float)
    result = _icp(_cloud(transform_points(T, arm)), _cloud(target_points, target_normals), limits, np.eye(4))
    correction = np.asarray(result.transformation)
    refined = correction @ T
    translation, rotation = _camera_motion(T, refined)
    fit = dict(translation=translation, rotation=rotation, fitness=float(result.fitness), rmse=float(result.inlier_rmse))
    if result.fitness < limits.min_fitness:
        return refused(f"poor fit: {result.fitness:.0%} of the {len(arm)} arm points fitted, fewer than "
                       f"{limits.min_fitness:.0%}", **fit)
    if result.inlier_rmse > limits.max_rmse:
        return refused(f"poor fit: residual {result.inlier_rmse * 1000:.1f} mm RMS, above {limits.max_rmse * 1000:.1f} mm", **fit)
    if translation > limits.max_translation or rotation > limits.max_rotation_deg:
        return refused(f"correction {translation * 1000:.1f} mm / {rotation:.2f} deg beyond the bound "
                       f"{limits.max_translation * 1000:.0f} mm / {limits.max_rotation_deg:.1f} deg", **fit)
    return Refinement(True, "", refined, correction, translation, rotation, float(result.fitness),
                      float(result.inlier_rmse), len(arm))


class ExtrinsicRefiner:
    """A robot's surface and the limits of a fit: refines the extrinsic of clouds that show the robot."""

    def __init__(self, surface: RobotSurface, limits: RefinementLimits = RefinementLimits()) -> None:
        self.surface = surface
        self.limits = limits

    def refine(self, xyz: np.ndarray, T_world_optical: np.ndarray, joint_positions: dict[str, float]) -> Refinement:
        """:func:`refine_extrinsic` of one organized cloud with the robot at ``joint_positions`` (its stamp's)."""
        return refine_extrinsic(xyz, T_world_optical, self.surface.posed(joint_positions), self.limits)

    def calibrate(self, T_world_optical: np.ndarray,
                  clouds: Iterable[tuple[np.ndarray, dict[str, float]]]) -> "EpisodeCalibration":
        """One fixed camera's extrinsic from several of its clouds (organized xyz, joint positions at its stamp)."""
        return EpisodeCalibration(np.asarray(T_world_optical, float),
                                  [self.refine(xyz, T_world_optical, joints) for xyz, joints in clouds])


@dataclass
class EpisodeCalibration:
    """One fixed camera's extrinsic over an episode: the accepted refinements of its clouds combined
    (rotations averaged, translations averaged), the given extrinsic when none was accepted."""

    nominal: np.ndarray
    fits: list[Refinement] = field(default_factory=list)

    @property
    def accepted(self) -> list[Refinement]:
        return [f for f in self.fits if f.accepted]

    @property
    def T_world_optical(self) -> np.ndarray:
        accepted = self.accepted
        if not accepted:
            return self.nominal
        T = np.eye(4)
        T[:3, :3] = Rotation.from_matrix(np.stack([f.T_world_optical[:3, :3] for f in accepted])).mean().as_matrix()
        T[:3, 3] = np.mean([f.T_world_optical[:3, 3] for f in accepted], axis=0)
        return T

    def to_json(self) -> dict:
        translation, rotation = _camera_motion(self.nominal, self.T_world_optical)
        return {"refined": bool(self.accepted), "T_world_optical": self.T_world_optical.tolist(),
                "nominal_T_world_optical": self.nominal.tolist(), "translation_m": round(translation, 6),
                "rotation_deg": round(rotation, 5), "fits": [f.to_json() for f in self.fits]}
