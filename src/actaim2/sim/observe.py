"""The simulator's eyes: a camera rig rendered through one render path, with optional realism.

:class:`CameraRig` is what the Python API (``SimEnv.observe``), the ROS node and the
benchmark use. It owns the renderer, renders each camera as the sensor model shapes it (field of
view, a separate colour camera registered into the depth pixels), re-samples extrinsic jitter
and systematic depth errors on every reset, and can render with some entities hidden - the paper's O_init / O_final observations are taken with
the robot occluded, which in simulation means "not drawn, not occluding".
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sapien

from actaim2.geometry import transform_points
from actaim2.profiling import timed
from actaim2.sim.cameras import CameraFrame, CameraSpec
from actaim2.sim.registration import register_colour
from actaim2.sim.render_path import make_renderer
from actaim2.sim.sensor_noise import SensorNoise


@dataclass(frozen=True)
class Observation:
    """Frames of every camera at one sim time, with the nominal camera specs they belong to."""

    frames: dict[str, CameraFrame]
    cameras: dict[str, CameraSpec]
    sim_time: float
    hidden: frozenset[int]  # per_scene_ids left out of this observation (e.g. the robot's links)

    def points_world(self, name: str) -> np.ndarray:
        """(H, W, 3) points of one camera in ``world`` through its *nominal* extrinsics (what a
        consumer of /tf_static computes; with extrinsic jitter on, this is where the error shows)."""
        return transform_points(self.cameras[name].T_world_optical, self.frames[name].xyz)


class CameraRig:
    """Cameras attached to a SAPIEN scene."""

    def __init__(
        self,
        scene: sapien.Scene,
        cameras: list[CameraSpec],
        render_path: str,
        noise: SensorNoise = SensorNoise(),
        seed: int = 0,
    ) -> None:
        """``render_path`` must be resolved (``sapien`` or ``raycast``, see
        ``actaim2.sim.render_path.resolve_render_path``)."""
        self.cameras = {c.name: c for c in cameras}
        self.noise = noise
        self.render_path = render_path
        self._rendered = [noise.camera_geometry(c) for c in cameras]
        colour_cameras = [c.colour for c in self._rendered if c.colour is not None]
        self._renderer = make_renderer(render_path, scene, self._rendered + colour_cameras)
        self.reset(seed)

    def reset(self, seed: int) -> None:
        """New episode: reseed the noise and draw this episode's extrinsic and systematic depth errors."""
        self._rng = np.random.default_rng(seed)
        # Where each camera renders from this episode: the simulator's truth, for measurements (never for a
        # consumer of the clouds, which knows the nominal pose alone).
        self.render_poses = {cam.name: cam.T_world_optical for cam in self._rendered}
        if self.noise.affects_extrinsics:
            poses = self.noise.jitter_poses(self._rendered, self._rng)
            for cam in self._rendered:  # a colour camera moves with its depth camera
                if cam.colour is not None:
                    poses[cam.colour.name] = poses[cam.name] @ cam.T_optical_colour
            self._renderer.set_camera_poses(poses)
            self.render_poses.update(poses)
        self._biases = self.noise.draw_biases(self._rendered, self._rng)

    @timed("render")
    def observe(self, sim_time: float, hidden: set[int] = frozenset()) -> Observation:
        """Render every camera; entities whose per_scene_id is in ``hidden`` are left out."""
        rendered = self._renderer.render(set(hidden))
        specular = self._renderer.specular_entities() if self.noise.specular_lobe_deg > 0 else frozenset()
        frames = {}
        for cam in self._rendered:
            frame = rendered[cam.name]
            if self.noise.affects_depth:
                frame = self.noise.apply(frame, self._rng, specular, self._biases[cam.name])
            if cam.colour is not None:  # registered after the depth errors, as the driver does with measured depth
                frame = register_colour(frame, cam, rendered[cam.colour.name])
            frames[cam.name] = frame
        return Observation(frames, self.cameras, sim_time, frozenset(hidden))
