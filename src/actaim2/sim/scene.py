"""The SAPIEN world: PhysX CPU scene, ground, lights, one robot and at most one articulated object.

Physics runs on PhysX's CPU system at a fixed step (240 Hz by default). A render system is
attached only when asked (``render=True``): SAPIEN cannot create one without a Vulkan device,
and a physics-only scene is what data collection and tests need when no camera renders
through SAPIEN (the ray-casting camera path reads collision shapes and entity poses only).

``world`` is the robot's root link frame (DESIGN.md): the robot base sits at the origin on
the floor (z = 0), objects stand in front of it along +x.
"""
from __future__ import annotations

from pathlib import Path

import sapien

from actaim2.robots import RobotSpec
from actaim2.sim.objects.hulls import HullCache
from actaim2.sim.objects.loader import LoadedObject, load_object, place
from actaim2.sim.robot import DriveGains, SimRobot

GROUND_FRICTION = 0.8


class SimScene:
    """Owns the SAPIEN scene and what stands in it."""

    def __init__(self, robot: RobotSpec, timestep: float = 1.0 / 240.0, render: bool = False, gains: DriveGains = DriveGains()):
        if not 0.0 < timestep <= 0.05:
            raise ValueError(f"physics timestep must be in (0, 0.05] s, got {timestep}")
        systems = [sapien.physx.PhysxCpuSystem()]
        if render:
            systems.append(sapien.render.RenderSystem())
        self.render = render
        self.scene = sapien.Scene(systems)
        self.scene.set_timestep(timestep)
        self.timestep = timestep
        ground_material = sapien.physx.PhysxMaterial(GROUND_FRICTION, GROUND_FRICTION, 0.0)
        self.ground = self.scene.add_ground(0.0, render=render, material=ground_material)
        # The lights, kept for domain randomisation (actaim2.sim.randomisation), which re-draws them per episode.
        self.key_light: sapien.render.RenderDirectionalLightComponent | None = None
        self.fill_light: sapien.render.RenderPointLightComponent | None = None
        if render:
            self.scene.set_ambient_light([0.35, 0.35, 0.35])
            self.key_light = self.scene.add_directional_light([0.3, 0.6, -1.0], [0.7, 0.7, 0.7], shadow=False)
            self.fill_light = self.scene.add_point_light([0.4, -0.8, 1.6], [0.6, 0.6, 0.6], shadow=False)
        self.robot = SimRobot(self.scene, robot, keep_visuals=render, gains=gains)
        self.object: LoadedObject | None = None
        self._scale_asked: float | None = None  # the scale argument the current object was loaded with
        self.steps = 0

    @property
    def time(self) -> float:
        """Simulated seconds since the scene was built."""
        return self.steps * self.timestep

    def step(self, n: int = 1) -> None:
        """``n`` physics steps; the object's joint dynamics (friction clamps, toggle springs) are
        refreshed from the current state before each (a teleported toggle must not first feel
        the spring of where it was)."""
        dynamics = self.object.dynamics if self.object is not None else None
        for _ in range(n):
            if dynamics is not None:
                dynamics.step()
            self.scene.step()
        self.steps += n

    def load_object(self, folder: Path, front_distance: float | None = None, lateral: float = 0.0, yaw: float = 0.0,
                    scale: float | None = None, hulls: HullCache | None = None) -> LoadedObject:
        """Replace the current object with the one in ``folder`` (see :func:`load_object`; None:
        its recommended front distance and scale); the same object at the same scale again is
        only moved (episodes on one object skip the URDF parsing)."""
        folder = Path(folder).expanduser()
        if self.object is not None and self.object.folder == folder and self._scale_asked == scale:
            place(self.object, self.object.front_distance if front_distance is None else front_distance, lateral, yaw)
            return self.object
        # Load before removing: a folder that fails to load leaves the current scene as it was.
        loaded = load_object(self.scene, folder, front_distance=front_distance, lateral=lateral, yaw=yaw, scale=scale,
                             keep_visuals=self.render, hulls=hulls)
        self.remove_object()
        self.object, self._scale_asked = loaded, scale
        return self.object

    def remove_object(self) -> None:
        if self.object is not None:
            self.scene.remove_articulation(self.object.articulation)
            self.object = None

    def robot_entity_ids(self) -> set[int]:
        """``per_scene_id`` of every robot link entity (what a robot-hidden observation leaves out)."""
        return {link.entity.per_scene_id for link in self.robot.links}

    def object_entity_ids(self) -> set[int]:
        return set() if self.object is None else {link.entity.per_scene_id for link in self.object.links}
