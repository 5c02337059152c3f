"""Sensor realism for sim-to-real work: time-of-flight depth errors, the colour camera's
registration, the real field of view, and extrinsic mistakes.

A rendered depth image is perfect; a real Azure Kinect's is not. The effects that matter to a
point-cloud policy are modelled, each with one switch (0 or False disables it). The numbers of
the ``azure_kinect`` preset come from the Azure Kinect DK hardware specification where it gives
one; where it gives none, the preset says so and the value is a choice.
  * random range error along each ray, growing with distance: ``depth_noise_std`` is the
    standard deviation per metre of depth;
  * systematic range error: one bias per camera and scene reset, drawn uniformly within
    +-(``systematic_error`` + ``systematic_error_per_metre`` x depth);
  * random missing returns (``dropout_rate``);
  * depth discontinuities, where a ToF pixel mixes foreground and background
    (``edge_jump_ratio``: a jump to a 4-neighbour larger than this fraction of the nearer
    depth; relative, so that a floor seen far away at a low angle is not taken for an edge).
    The depth engine invalidates such pixels, except a fraction ``flying_pixel_rate`` that
    survive as flying pixels: a depth between the two surfaces, on the pixel's ray;
  * missing returns on surfaces seen at grazing incidence (``grazing_angle_deg``);
  * missing returns where too little infrared comes back (``min_ir_signal``): the signal is
    the surface's albedo x cos(incidence) / (depth / 1 m)^2, the albedo taken from the rendered
    colour (linearised) as the closest stand-in for 850 nm reflectivity a renderer has;
  * specular surfaces (metallic and glossy in the render material) mirror the illumination
    away: they return only within ``specular_lobe_deg`` of normal incidence;
  * the documented field of view (``nominal_fov``: :meth:`CameraSpec.with_nominal_fov`);
  * a separate colour camera (``colour_registration``): colour comes from the device's RGB
    camera, 32 mm away, registered into the depth pixels as the driver does
    (``actaim2.sim.registration``);
  * extrinsic jitter: the camera renders from a pose that differs from the nominal one that
    /tf_static publishes, like an imperfect calibration (``extrinsic_translation_std`` in m,
    ``extrinsic_rotation_std_deg``), sampled once per scene reset.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.sim.cameras import CameraFrame, CameraSpec


@dataclass(frozen=True)
class SensorNoise:
    depth_noise_std: float = 0.0  # per metre of depth
    systematic_error: float = 0.0  # m
    systematic_error_per_metre: float = 0.0
    dropout_rate: float = 0.0
    edge_jump_ratio: float = 0.0
    flying_pixel_rate: float = 0.0
    grazing_angle_deg: float = 0.0
    min_ir_signal: float = 0.0
    specular_lobe_deg: float = 0.0
    nominal_fov: bool = False
    colour_registration: bool = False
    extrinsic_translation_std: float = 0.0
    extrinsic_rotation_std_deg: float = 0.0

    @classmethod
    def preset(cls, name: str, rig: str | None = None) -> "SensorNoise":
        """``none``; ``tof``: a generic ToF camera (2 mm of noise at 1 m, edge and
        grazing-angle invalidation, a calibration good to ~5 mm and ~0.5 degree);
        ``azure_kinect``: the Azure Kinect DK as documented; ``rig``: the default of ``rig``
        (:data:`RIG_DEFAULTS`: realism is on for the azure_kinect rig, off for ring5)."""
        if name == "rig":
            if rig not in RIG_DEFAULTS:
                raise ValueError(f"sensor noise preset 'rig' needs a rig, one of {list(RIG_DEFAULTS)}; got {rig!r}")
            name = RIG_DEFAULTS[rig]
        if name == "none":
            return cls()
        if name == "tof":
            return cls(
                depth_noise_std=0.002,
                dropout_rate=0.01,
                edge_jump_ratio=0.05,
                grazing_angle_deg=80.0,
                extrinsic_translation_std=0.005,
                extrinsic_rotation_std_deg=0.5,
            )
        if name == "azure_kinect":
            return cls(
                # Azure Kinect DK hardware specification: random error std <= 17 mm; taken as
                # reached at 3.86 m, the far end of NFOV unbinned, growing linearly (4.4 mm at 1 m).
                depth_noise_std=0.017 / 3.86,
                # ... systematic error < 11 mm + 0.1% of distance.
                systematic_error=0.011,
                systematic_error_per_metre=0.001,
                # Not in the documentation (the depth engine invalidates mixed pixels at edges,
                # some survive as flying pixels): chosen.
                edge_jump_ratio=0.05,
                flying_pixel_rate=0.3,
                # Not in the documentation: chosen.
                grazing_angle_deg=80.0,
                # ... operating ranges hold for 15-95% reflectivity at 850 nm: a 15% surface
                # still returns at 5.46 m, the far end of NFOV binned.
                min_ir_signal=0.15 / 5.46**2,
                # Not in the documentation: chosen.
                specular_lobe_deg=20.0,
                # ... NFOV 75 x 65 degrees (its pinhole equivalent).
                nominal_fov=True,
                # ... a separate colour camera, 90 x 59 degrees (16:9), ~32 mm from the depth camera.
                colour_registration=True,
                # The hand-eye calibration's error, not the sensor's: as ``tof``.
                extrinsic_translation_std=0.005,
                extrinsic_rotation_std_deg=0.5,
            )
        raise ValueError(f"unknown sensor noise preset '{name}': use one of {SENSOR_NOISE_PRESETS}")

    @property
    def affects_depth(self) -> bool:
        return any(v > 0 for v in (self.depth_noise_std, self.systematic_error, self.systematic_error_per_metre,
                                   self.dropout_rate, self.edge_jump_ratio, self.grazing_angle_deg, self.min_ir_signal,
                                   self.specular_lobe_deg))

    def camera_geometry(self, camera: CameraSpec) -> CameraSpec:
        """The camera as this model renders it: the documented field of view or the nominal
        pinhole, with its separate colour camera or without one."""
        if self.nominal_fov:
            camera = camera.with_nominal_fov()
        if not self.colour_registration and camera.colour is not None:
            camera = replace(camera, colour=None)
        return camera

    def draw_biases(self, cameras: list[CameraSpec], rng: np.random.Generator) -> dict[str, float]:
        """This reset's systematic error per camera, as a fraction in [-1, 1] of its bound."""
        return {cam.name: float(rng.uniform(-1.0, 1.0)) for cam in cameras}

    @property
    def affects_extrinsics(self) -> bool:
        return self.extrinsic_translation_std > 0 or self.extrinsic_rotation_std_deg > 0

    def jitter_poses(self, cameras: list[CameraSpec], rng: np.random.Generator) -> dict[str, np.ndarray]:
        """True render poses T_world_optical per camera: the nominal pose moved by a small
        random rigid motion expressed in the camera's own frame."""
        poses = {}
        for cam in cameras:
            delta = np.eye(4)
            delta[:3, :3] = Rotation.from_rotvec(rng.normal(0.0, np.deg2rad(self.extrinsic_rotation_std_deg), 3)).as_matrix()
            delta[:3, 3] = rng.normal(0.0, self.extrinsic_translation_std, 3)
            poses[cam.name] = cam.T_world_optical @ delta
        return poses

    def apply(
        self, frame: CameraFrame, rng: np.random.Generator, specular_ids: frozenset[int] = frozenset(), bias: float = 0.0
    ) -> CameraFrame:
        """A copy of ``frame`` with the depth effects; points move along their rays.

        ``specular_ids``: entities whose material is specular (from the renderer); ``bias``:
        this reset's systematic error as a fraction of its bound (:meth:`draw_biases`).
        """
        if not self.affects_depth:
            return frame
        xyz = frame.xyz.copy()
        z = xyz[..., 2]
        new_z = z.copy()
        drop = np.zeros(z.shape, dtype=bool)
        if self.edge_jump_ratio > 0:
            edges, partner = _depth_edges(z, self.edge_jump_ratio)
            flying = edges & np.isfinite(partner) & (rng.random(z.shape) < self.flying_pixel_rate)
            mix = rng.random(z.shape)
            new_z[flying] = mix[flying] * z[flying] + (1.0 - mix[flying]) * partner[flying]
            drop |= edges & ~flying
        cos_incidence = _cos_incidence(xyz)
        if self.grazing_angle_deg > 0:
            drop |= cos_incidence < np.cos(np.deg2rad(self.grazing_angle_deg))  # NaN (unknown normal) compares False: kept
        if self.min_ir_signal > 0:
            albedo = (frame.rgb.astype(np.float32).mean(axis=-1) / 255.0) ** 2.2  # sRGB-like -> linear
            with np.errstate(invalid="ignore"):
                drop |= albedo * np.nan_to_num(cos_incidence, nan=1.0) / z**2 < self.min_ir_signal
        if self.specular_lobe_deg > 0 and specular_ids:
            specular = np.isin(frame.segmentation, np.fromiter(specular_ids, dtype=np.int64))
            drop |= specular & ~(cos_incidence >= np.cos(np.deg2rad(self.specular_lobe_deg)))
        if self.dropout_rate > 0:
            drop |= rng.random(z.shape) < self.dropout_rate
        new_z += bias * (self.systematic_error + self.systematic_error_per_metre * new_z)
        if self.depth_noise_std > 0:
            new_z += rng.normal(0.0, 1.0, z.shape) * self.depth_noise_std * new_z
        with np.errstate(invalid="ignore", divide="ignore"):
            xyz *= (new_z / z)[..., None]
        xyz[drop] = np.nan
        valid = np.isfinite(xyz[..., 2])
        rgb = np.where(valid[..., None], frame.rgb, 0).astype(np.uint8)
        segmentation = np.where(valid, frame.segmentation, 0).astype(np.int32)
        return CameraFrame(frame.name, xyz.astype(np.float32), rgb, segmentation)


SENSOR_NOISE_PRESETS = ("none", "tof", "azure_kinect", "rig")
RIG_DEFAULTS = {"ring5": "none", "azure_kinect": "azure_kinect"}  # the sensor model each rig gets unless asked


def _depth_edges(z: np.ndarray, ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixels whose depth differs from a 4-neighbour by more than ``ratio`` times the nearer
    of the two depths (both pixels of the pair are marked), and for each the depth across its
    largest jump (inf where that is a no-return: the silhouette against nothing)."""
    zf = np.nan_to_num(z, nan=np.inf)
    padded = np.pad(zf, 1, constant_values=np.inf)
    neighbours = np.stack([padded[:-2, 1:-1], padded[2:, 1:-1], padded[1:-1, :-2], padded[1:-1, 2:]])
    with np.errstate(invalid="ignore"):
        jump = np.abs(neighbours - zf)
        is_edge = jump > ratio * np.minimum(neighbours, zf)
        # the image border is no edge: only real neighbours count
        is_edge[0, 0, :] = is_edge[1, -1, :] = is_edge[2, :, 0] = is_edge[3, :, -1] = False
    jump = np.where(is_edge, np.nan_to_num(jump, nan=np.inf), -1.0)
    partner = np.take_along_axis(neighbours, jump.argmax(axis=0)[None], axis=0)[0]
    edges = is_edge.any(axis=0) & np.isfinite(z)
    return edges, partner


def _cos_incidence(xyz: np.ndarray) -> np.ndarray:
    """|cos| of the angle between each pixel's surface normal (from its neighbours' points) and
    its viewing ray; NaN where the normal is unknown (a neighbour without a return)."""
    du = np.zeros_like(xyz)
    dv = np.zeros_like(xyz)
    du[:, 1:-1] = xyz[:, 2:] - xyz[:, :-2]
    dv[1:-1] = xyz[2:] - xyz[:-2]
    normal = np.cross(du, dv)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.abs(np.sum(normal * xyz, axis=-1)) / (np.linalg.norm(normal, axis=-1) * np.linalg.norm(xyz, axis=-1))
