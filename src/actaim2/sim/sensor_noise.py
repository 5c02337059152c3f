"""Sensor realism for sim-to-real work: time-of-flight depth errors and extrinsic mistakes.

A rendered depth image is perfect; a real Azure Kinect's is not. The effects that matter to a
point-cloud policy are modelled, each with one parameter (0 disables it):
  * range noise along each ray, proportional to the depth - ``depth_noise_std`` is the
    standard deviation at 1 m (measured Azure Kinect noise is 1-2 mm at 1 m and grows
    slowly; the datasheet bounds it by 17 mm over the whole range);
  * random missing returns (``dropout_rate``);
  * missing returns at depth discontinuities, where a ToF pixel mixes foreground and
    background and the driver invalidates it (``edge_jump_ratio``: a jump to a 4-neighbour
    larger than this fraction of the pixel's depth; relative, so that a floor seen far away at
    a low angle is not taken for an edge);
  * missing returns on surfaces seen at grazing incidence (``grazing_angle_deg``);
  * extrinsic jitter: the camera renders from a pose that differs from the nominal one that
    /tf_static publishes, like an imperfect calibration (``extrinsic_translation_std`` in m,
    ``extrinsic_rotation_std_deg``), sampled once per scene reset.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from actaim2.sim.cameras import CameraFrame, CameraSpec


@dataclass(frozen=True)
class SensorNoise:
    depth_noise_std: float = 0.0
    dropout_rate: float = 0.0
    edge_jump_ratio: float = 0.0
    grazing_angle_deg: float = 0.0
    extrinsic_translation_std: float = 0.0
    extrinsic_rotation_std_deg: float = 0.0

    @classmethod
    def preset(cls, name: str) -> "SensorNoise":
        """``none``, or ``tof``: an Azure-Kinect-like camera (a few mm of noise at 1 m, edge
        and grazing-angle invalidation, a calibration good to ~5 mm and ~0.5 degree)."""
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
        raise ValueError(f"unknown sensor noise preset '{name}': use one of {SENSOR_NOISE_PRESETS}")

    @property
    def affects_depth(self) -> bool:
        return any(v > 0 for v in (self.depth_noise_std, self.dropout_rate, self.edge_jump_ratio, self.grazing_angle_deg))

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

    def apply(self, frame: CameraFrame, rng: np.random.Generator) -> CameraFrame:
        """A copy of ``frame`` with depth noise and dropouts; points move along their rays."""
        if not self.affects_depth:
            return frame
        xyz = frame.xyz.copy()
        z = xyz[..., 2]
        drop = np.zeros(z.shape, dtype=bool)
        if self.edge_jump_ratio > 0:
            drop |= _depth_edges(z, self.edge_jump_ratio)
        if self.grazing_angle_deg > 0:
            drop |= _grazing(xyz, np.deg2rad(self.grazing_angle_deg))
        if self.dropout_rate > 0:
            drop |= rng.random(z.shape) < self.dropout_rate
        if self.depth_noise_std > 0:
            noisy_z = z + rng.normal(0.0, 1.0, z.shape) * self.depth_noise_std * z
            with np.errstate(invalid="ignore", divide="ignore"):
                xyz *= (noisy_z / z)[..., None]
        xyz[drop] = np.nan
        valid = np.isfinite(xyz[..., 2])
        rgb = np.where(valid[..., None], frame.rgb, 0).astype(np.uint8)
        segmentation = np.where(valid, frame.segmentation, 0).astype(np.int32)
        return CameraFrame(frame.name, xyz.astype(np.float32), rgb, segmentation)


SENSOR_NOISE_PRESETS = ("none", "tof")


def _depth_edges(z: np.ndarray, ratio: float) -> np.ndarray:
    """Pixels whose depth differs from a 4-neighbour by more than ``ratio`` times the nearer
    of the two depths (both pixels of the pair are marked)."""
    zf = np.nan_to_num(z, nan=np.inf)
    edges = np.zeros(z.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        # a pixel next to a no-return (inf) counts as an edge: the silhouette against nothing
        dv = np.abs(np.diff(zf, axis=0)) > ratio * np.minimum(zf[1:], zf[:-1])
        du = np.abs(np.diff(zf, axis=1)) > ratio * np.minimum(zf[:, 1:], zf[:, :-1])
    edges[1:] |= dv
    edges[:-1] |= dv
    edges[:, 1:] |= du
    edges[:, :-1] |= du
    return edges & np.isfinite(z)


def _grazing(xyz: np.ndarray, max_angle: float) -> np.ndarray:
    """Pixels whose surface normal (from neighbouring points) is more than ``max_angle`` away
    from the viewing ray."""
    du = np.zeros_like(xyz)
    dv = np.zeros_like(xyz)
    du[:, 1:-1] = xyz[:, 2:] - xyz[:, :-2]
    dv[1:-1] = xyz[2:] - xyz[:-2]
    normal = np.cross(du, dv)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.abs(np.sum(normal * xyz, axis=-1)) / (np.linalg.norm(normal, axis=-1) * np.linalg.norm(xyz, axis=-1))
        return cos < np.cos(max_angle)  # NaN (unknown normal) compares False: kept
