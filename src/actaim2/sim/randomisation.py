"""Domain randomisation: what a real rig may look like and a rendered one does not, drawn per episode.

A policy pretrained in simulation meets one real camera: other light, other colours, the object a
little elsewhere, a noisier or cleaner depth sensor, a hand-eye calibration a few millimetres off.
:class:`DomainRandomisation` holds the ranges (``domain_randomisation.yaml``, the ``default``);
:class:`Randomiser` applies one draw to a simulator scene at every reset:

* lighting: the ambient light, the directional key light (intensity, direction) and the point
  fill light, all of one colour temperature (SAPIEN's lights; its ``minimal`` shader lights them);
* colours: each colour of the object (its materials grouped by original colour, so panels of one
  colour stay one colour and a handle stays distinct) and the ground's, drawn in HSV
  (``base_color`` of SAPIEN's render materials);
* placement: the object's jitter before the robot (:meth:`DomainRandomisation.placement_jitter`,
  which :class:`~actaim2.sim.env.SimEnv` draws with);
* depth noise: the preset sensor model of :mod:`actaim2.sim.sensor_noise`, its random range error
  scaled per episode;
* extrinsic jitter: the same model's per-reset camera pose error, with this configuration's size.

Every draw comes from the reset seed (its own stream, so placement and sensor noise draw what
they drew without randomisation), so the same seed gives the same picture. Lighting and colours
need the SAPIEN render path: ray casting draws flat colours per entity, and the draw records
that they were not applied.
"""
from __future__ import annotations

import colorsys
import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np
import sapien

from actaim2.config_fields import check_fields, load_yaml_config
from actaim2.sim.sensor_noise import SensorNoise

if TYPE_CHECKING:
    from actaim2.sim.observe import CameraRig
    from actaim2.sim.scene import SimScene

DEFAULT_FILE = Path(__file__).resolve().parent / "domain_randomisation.yaml"
STREAM = 0xD0A1  # the randomisation's own random stream of a reset seed
RANGES = ("ambient_intensity", "key_light_intensity", "key_light_elevation_deg", "key_light_azimuth_deg",
          "fill_light_intensity", "colour_temperature_k", "object_hue", "object_saturation", "object_value",
          "ground_hue", "ground_saturation", "ground_value", "depth_noise_scale")
UNIT_RANGES = ("object_hue", "object_saturation", "object_value", "ground_hue", "ground_saturation", "ground_value")


@dataclass(frozen=True)
class DomainRandomisation:
    """Per-episode ranges; pairs are [low, high] drawn uniformly. Field meanings: ``domain_randomisation.yaml``."""

    ambient_intensity: tuple[float, float] = (0.15, 0.5)
    key_light_intensity: tuple[float, float] = (0.3, 1.1)
    key_light_elevation_deg: tuple[float, float] = (30.0, 85.0)
    key_light_azimuth_deg: tuple[float, float] = (-180.0, 180.0)
    fill_light_intensity: tuple[float, float] = (0.0, 0.9)
    colour_temperature_k: tuple[float, float] = (3000.0, 7500.0)
    object_hue: tuple[float, float] = (0.0, 1.0)
    object_saturation: tuple[float, float] = (0.0, 0.8)
    object_value: tuple[float, float] = (0.25, 1.0)
    ground_hue: tuple[float, float] = (0.0, 1.0)
    ground_saturation: tuple[float, float] = (0.0, 0.4)
    ground_value: tuple[float, float] = (0.3, 0.9)
    placement_front: float = 0.04  # m
    placement_lateral: float = 0.08  # m
    placement_yaw_deg: float = 10.0
    sensor_noise: str = "rig"  # SensorNoise preset of the depth model
    depth_noise_scale: tuple[float, float] = (0.5, 2.0)
    extrinsic_translation_std: float = 0.01  # m
    extrinsic_rotation_std_deg: float = 1.0

    def __post_init__(self) -> None:
        problems = []
        for name in RANGES:
            value = tuple(float(v) for v in getattr(self, name))
            object.__setattr__(self, name, value)
            if len(value) != 2 or not value[0] <= value[1]:
                problems.append(f"{name} must be [low, high] with low <= high, got {list(value)}")
            elif value[0] < 0 and name != "key_light_azimuth_deg":
                problems.append(f"{name} must not be negative, got {list(value)}")
            elif name in UNIT_RANGES and value[1] > 1.0:
                problems.append(f"{name} is a fraction: within [0, 1], got {list(value)}")
        if not (0.0 <= self.key_light_elevation_deg[0] and self.key_light_elevation_deg[1] <= 90.0):
            problems.append(f"key_light_elevation_deg must lie within [0, 90], got {list(self.key_light_elevation_deg)}")
        if min(self.colour_temperature_k) < 1000.0 or max(self.colour_temperature_k) > 40000.0:
            problems.append(f"colour_temperature_k must lie within [1000, 40000] K, got {list(self.colour_temperature_k)}")
        for name in ("placement_front", "placement_lateral", "placement_yaw_deg", "extrinsic_translation_std",
                     "extrinsic_rotation_std_deg"):
            if getattr(self, name) < 0:
                problems.append(f"{name} must not be negative, got {getattr(self, name)}")
        if problems:
            raise ValueError("invalid domain randomisation: " + "; ".join(problems))

    def to_dict(self) -> dict:
        """Plain JSON/YAML types (lists for pairs), every field: what dataset.json records."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: Mapping) -> "DomainRandomisation":
        """The inverse of :meth:`to_dict`; unknown keys are an error (a typo must not pass silently)."""
        check_fields(cls, data, "domain randomisation")
        return cls(**dict(data))

    def placement_jitter(self) -> tuple[float, float, float]:
        """(front m, lateral m, yaw rad): the +- ranges SimEnv.reset draws the object's placement from."""
        return self.placement_front, self.placement_lateral, math.radians(self.placement_yaw_deg)

    def sensor_noise_model(self, rig: str) -> SensorNoise:
        """The depth and calibration model of a rig's episodes: the preset, its extrinsic error this size."""
        return replace(SensorNoise.preset(self.sensor_noise, rig), extrinsic_translation_std=self.extrinsic_translation_std,
                       extrinsic_rotation_std_deg=self.extrinsic_rotation_std_deg)


def load_randomisation(name_or_path: str | Path) -> DomainRandomisation:
    """``default`` (the bundled ``domain_randomisation.yaml``) or a YAML file of :class:`DomainRandomisation` fields."""
    path = DEFAULT_FILE if str(name_or_path) == "default" else Path(name_or_path)
    if not path.is_file():
        raise FileNotFoundError(f"no domain randomisation file {path} (give a YAML, or 'default')")
    return load_yaml_config(DomainRandomisation, path)


def colour_temperature_rgb(kelvin: float) -> np.ndarray:
    """The RGB colour (brightest channel 1) of a black body at ``kelvin``.

    Tanner Helland's fits of the black-body colours to sRGB (1000-40000 K, a few percent): warm
    bulbs (2700-3000 K) are orange, daylight (6500 K) is white, overcast sky (7500 K) bluish.
    """
    t = kelvin / 100.0
    red = 255.0 if t <= 66 else 329.698727446 * (t - 60) ** -0.1332047592
    green = 99.4708025861 * math.log(t) - 161.1195681661 if t <= 66 else 288.1221695283 * (t - 60) ** -0.0755148492
    blue = 255.0 if t >= 66 else (0.0 if t <= 19 else 138.5177312231 * math.log(t - 10) - 305.0447927307)
    rgb = np.clip([red, green, blue], 0.0, 255.0) / 255.0
    return rgb / rgb.max()


def _uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def _hsv(rng: np.random.Generator, hue: tuple[float, float], saturation: tuple[float, float],
         value: tuple[float, float]) -> list[float]:
    return list(colorsys.hsv_to_rgb(_uniform(rng, hue) % 1.0, _uniform(rng, saturation), _uniform(rng, value)))


def _materials(entity: sapien.Entity) -> list[sapien.render.RenderMaterial]:
    """The distinct render materials of an entity's visual shapes, in shape order (empty without visuals)."""
    body = entity.find_component_by_type(sapien.render.RenderBodyComponent)
    found: list[sapien.render.RenderMaterial] = []
    for shape in body.render_shapes if body is not None else []:
        parts = shape.parts if isinstance(shape, sapien.render.RenderShapeTriangleMesh) else [shape]
        for part in parts:
            if not any(part.material is m for m in found):
                found.append(part.material)
    return found


def _rounded(values) -> list[float]:
    return [round(float(v), 4) for v in values]


class Randomiser:
    """Applies a :class:`DomainRandomisation` to one simulator scene and its camera rig, a draw per reset.

    One per scene (``SimEnv.randomiser``): it reads the object's original colours before its
    first recolouring, so a second randomiser would take recoloured materials for originals.
    """

    def __init__(self, config: DomainRandomisation, sim: "SimScene", rig: "CameraRig | None") -> None:
        """``rig``'s sensor model is the base whose random depth error each episode scales."""
        self.config, self.sim, self.rig = config, sim, rig
        self.base_noise = rig.noise if rig is not None else None
        self._coloured: tuple[object, list] | None = None  # (loaded object, its materials by original colour)

    def apply(self, seed: int) -> dict:
        """Draw this reset's lighting, colours and depth noise from ``seed`` and set them; returns the draw.

        Drawn in a fixed order whatever the render path (lighting, depth noise, then colours, whose
        count follows the object's materials), so a seed means the same light on every path.
        """
        c = self.config
        rng = np.random.default_rng([int(seed), STREAM])
        temperature = _uniform(rng, c.colour_temperature_k)
        elevation, azimuth = np.deg2rad(_uniform(rng, c.key_light_elevation_deg)), np.deg2rad(_uniform(rng, c.key_light_azimuth_deg))
        lighting = {
            "colour_temperature_k": round(temperature, 1),
            "ambient": round(_uniform(rng, c.ambient_intensity), 4),
            "key": round(_uniform(rng, c.key_light_intensity), 4),
            "key_direction": _rounded(-np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                                                 np.sin(elevation)])),
            "fill": round(_uniform(rng, c.fill_light_intensity), 4),
        }
        depth_scale = _uniform(rng, c.depth_noise_scale)
        draw: dict = {"lighting": lighting, "depth_noise_scale": round(depth_scale, 4), "colours": None,
                      "rendered": self.sim.render}
        if self.rig is not None:
            self.rig.noise = replace(self.base_noise, depth_noise_std=self.base_noise.depth_noise_std * depth_scale)
        if self.sim.render:
            self._set_lights(lighting)
            draw["colours"] = self._set_colours(rng)
        return draw

    def _set_lights(self, lighting: dict) -> None:
        tint = colour_temperature_rgb(lighting["colour_temperature_k"])
        self.sim.scene.set_ambient_light(list(lighting["ambient"] * tint))
        key = self.sim.key_light
        key.color = list(lighting["key"] * tint)
        # a directional light shines along its entity's x axis
        key.entity_pose = sapien.Pose(key.entity_pose.p, sapien.math.shortest_rotation(np.array([1.0, 0.0, 0.0], np.float32),
                                                                          np.asarray(lighting["key_direction"], np.float32)))
        self.sim.fill_light.color = list(lighting["fill"] * tint)

    def _set_colours(self, rng: np.random.Generator) -> dict:
        """Ground first, then the object's colours; returns the colours set.

        The object keeps its design: materials that share an original colour (the URDF loader
        gives every visual its own material, so a carcass is six materials of one colour) get one
        new colour, drawn in the order the colours first appear along the links.
        """
        c = self.config
        colours: dict = {"ground": [], "object": []}
        for material in _materials(self.sim.ground):
            rgb = _hsv(rng, c.ground_hue, c.ground_saturation, c.ground_value)
            material.base_color = [*rgb, 1.0]
            colours["ground"].append(_rounded(rgb))
        for original, materials in self._object_colours():
            rgb = _hsv(rng, c.object_hue, c.object_saturation, c.object_value)
            for material in materials:
                material.base_color = [*rgb, material.base_color[3]]
            colours["object"].append({"original": list(original), "colour": _rounded(rgb)})
        return colours

    def _object_colours(self) -> list[tuple[tuple[float, ...], list[sapien.render.RenderMaterial]]]:
        """The object's materials grouped by their original colour (read once per loaded object:
        later resets of the same object find them recoloured)."""
        obj = self.sim.object
        if obj is None:
            return []
        if self._coloured is None or self._coloured[0] is not obj:
            groups: dict[tuple[float, ...], list[sapien.render.RenderMaterial]] = {}
            for link in obj.links:
                for material in _materials(link.entity):
                    original = tuple(_rounded(material.base_color[:3]))
                    members = groups.setdefault(original, [])
                    if not any(material is m for m in members):
                        members.append(material)
            self._coloured = (obj, list(groups.items()))
        return self._coloured[1]
