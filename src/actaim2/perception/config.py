"""One perception configuration per camera rig: what ties collected data, checkpoints and serving.

A :class:`PerceptionConfig` holds every setting that changes what the networks see: the rig,
the workspace cube, fusion, the robot filter, the simulator's render path, and how views are
rendered (resolution, channels, normalisation, splatting). Each rig has one YAML in
``configs/`` (:func:`load_perception_config` takes a rig name or a path):

* collection fixes the *capture* fields (:data:`CAPTURE_FIELDS`: rig, cube, robot filter,
  render path) and writes them into ``dataset.json``;
* the *view* fields (:data:`VIEW_FIELDS`) are the checkpoint's choice, since views are
  recomputed from the stored pictures; training writes the whole configuration
  (:meth:`PerceptionConfig.to_dict`, :meth:`PerceptionConfig.digest`) into every checkpoint;
* ``fusion_node`` loads the rig's YAML and stamps every ``OrthoViews`` with the digest.

:func:`check_compatible` refuses a mismatch (dataset vs training run, checkpoint vs serving)
with a message naming each differing field and both values.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Iterable, Mapping

import yaml

from actaim2.config_fields import check_fields, load_yaml_config
from actaim2.perception.fusion import FusionConfig
from actaim2.perception.ortho_views import (
    CHANNELS,
    DEFAULT_DEPTH_TOLERANCE,
    DEFAULT_RESOLUTION,
    DEFAULT_SPLAT_RADIUS,
    SPLAT_RADIUS_RANGE,
)

CONFIG_DIR = Path(__file__).resolve().parent / "configs"
RENDER_PATHS = ("sapien", "raycast")  # how the simulator makes this rig's pictures (a real rig's data: sapien-trained)
NORMALISATIONS = ("rvt_cube",)  # view units of actaim2.perception.ortho_views, recorded so other units are refused
CAPTURE_FIELDS = ("rig", "center", "half_extent", "remove_robot_views", "self_filter_margin", "render_path")
VIEW_FIELDS = ("voxel_size", "outlier_neighbors", "outlier_std_ratio", "resolution", "channels", "normalisation",
               "splat_radius", "splat_depth_tolerance")
DIGEST_DECIMALS = 6  # floats are rounded before hashing: 1e-6 m is far below any setting that matters


class PerceptionMismatchError(ValueError):
    """Two perception configurations that must agree do not; the message names the fields."""


@dataclass(frozen=True)
class PerceptionConfig:
    rig: str  # camera rig (actaim2.sim.cameras.RIGS): ring5 or azure_kinect
    center: tuple[float, float, float]  # workspace cube centre, world (m): crop and views
    half_extent: float  # half the side of the workspace cube (m)
    remove_robot_views: bool = True  # views are robot-hidden (the policy is trained that way)
    self_filter_margin: float = 0.01  # m: points this close to the robot's collision geometry are removed
    render_path: str = "sapien"  # the simulator's renderer for this rig's training pictures
    voxel_size: float = 0.005  # m: voxel grid of the fused cloud; 0 keeps every point
    outlier_neighbors: int = 0  # statistical outlier removal: k neighbours; 0 disables it
    outlier_std_ratio: float = 2.0  # ... drop points whose mean k-NN distance exceeds mean + ratio * std
    resolution: int = DEFAULT_RESOLUTION  # px per view side
    channels: tuple[str, ...] = CHANNELS  # rendered channels, in this order (a subset of ortho_views.CHANNELS)
    normalisation: str = NORMALISATIONS[0]  # channel units (see ortho_views)
    splat_radius: float = DEFAULT_SPLAT_RADIUS  # px
    splat_depth_tolerance: float = DEFAULT_DEPTH_TOLERANCE  # m: splats this far behind the nearest are hidden

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", tuple(float(c) for c in self.center))
        object.__setattr__(self, "channels", tuple(self.channels))
        problems = []
        if len(self.center) != 3:
            problems.append(f"center needs 3 coordinates, got {len(self.center)}")
        if self.half_extent <= 0 or self.voxel_size < 0 or self.self_filter_margin < 0:
            problems.append("half_extent must be > 0, voxel_size and self_filter_margin >= 0")
        if self.render_path not in RENDER_PATHS:
            problems.append(f"render_path '{self.render_path}' is not one of {RENDER_PATHS}")
        if self.normalisation not in NORMALISATIONS:
            problems.append(f"normalisation '{self.normalisation}' is not one of {NORMALISATIONS}")
        unknown = [c for c in self.channels if c not in CHANNELS]
        if unknown or not self.channels or len(set(self.channels)) != len(self.channels):
            problems.append(f"channels must be distinct names from {CHANNELS}, got {list(self.channels)}")
        if self.resolution < 8:
            problems.append(f"resolution {self.resolution} px is too small")
        low, high = SPLAT_RADIUS_RANGE
        if not low - 1e-9 <= self.splat_radius <= high:
            problems.append(f"splat_radius must lie in [{low:.3f}, {high}] px, got {self.splat_radius}")
        if self.splat_depth_tolerance <= 0:
            problems.append("splat_depth_tolerance must be > 0 m")
        if problems:
            raise ValueError("invalid perception configuration: " + "; ".join(problems))

    @property
    def fusion(self) -> FusionConfig:
        """The fusion step's settings (crop cube, voxels, outliers)."""
        return FusionConfig(self.center, self.half_extent, self.voxel_size, self.outlier_neighbors, self.outlier_std_ratio)

    def to_dict(self) -> dict:
        """Plain JSON/YAML types (lists for tuples), every field."""
        data = asdict(self)
        data["center"], data["channels"] = list(self.center), list(self.channels)
        return data

    @classmethod
    def from_dict(cls, data: Mapping) -> "PerceptionConfig":
        """The inverse of :meth:`to_dict`; unknown keys are an error (a typo must not pass silently)."""
        check_fields(cls, data, "perception configuration")
        return cls(**dict(data))

    def replace(self, **changes) -> "PerceptionConfig":
        """A copy with some fields changed (validated), e.g. a checkpoint's own resolution."""
        return replace(self, **changes)

    def digest(self, names: Iterable[str] | None = None) -> str:
        """16 hex digits identifying the values of ``names`` (default: every field).

        Stable across processes, Python versions and float noise below 1e-6: a canonical JSON of
        the fields, floats rounded, hashed with SHA-256.
        """
        return _digest({name: self.to_dict()[name] for name in (names or self.to_dict())})

    def diff(self, other: "PerceptionConfig | Mapping", names: Iterable[str] | None = None) -> list[str]:
        """Names of the fields (of ``names``, default every field) whose values differ."""
        mine = self.to_dict()
        theirs = other.to_dict() if isinstance(other, PerceptionConfig) else dict(other)
        return [n for n in (names or mine) if _canonical(mine[n]) != _canonical(theirs.get(n, _MISSING))]


_MISSING = "<missing>"


def _canonical(value):
    """Rounded floats, lists for tuples: the form both digest and diff compare."""
    if isinstance(value, float):
        return round(value, DIGEST_DECIMALS)
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    return value


def _digest(values: Mapping) -> str:
    text = json.dumps({k: _canonical(v) for k, v in values.items()}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def capture_part(config: PerceptionConfig) -> dict:
    """The fields a dataset fixes (what collection writes into ``dataset.json``)."""
    data = config.to_dict()
    return {name: data[name] for name in CAPTURE_FIELDS}


def check_compatible(
    expected: PerceptionConfig | Mapping,
    actual: PerceptionConfig,
    names: Iterable[str] | None = None,
    sides: tuple[str, str] = ("expected", "actual"),
) -> None:
    """Raise :class:`PerceptionMismatchError` naming every field of ``names`` that differs.

    ``expected`` may be a plain dict (a ``dataset.json``'s capture part, a checkpoint's
    configuration); ``names`` defaults to every field (checkpoint vs serving); pass
    :data:`CAPTURE_FIELDS` to compare a dataset with a training run. ``sides`` name the two
    configurations in the message, e.g. ("dataset", "training run").
    """
    names = list(names or [f.name for f in fields(PerceptionConfig)])
    given = expected.to_dict() if isinstance(expected, PerceptionConfig) else dict(expected)
    differing = actual.diff(given, names)
    if differing:
        wanted = actual.to_dict()
        details = ", ".join(f"{n} ({sides[0]} {given.get(n, _MISSING)!r}, {sides[1]} {wanted[n]!r})" for n in differing)
        raise PerceptionMismatchError(
            f"perception configuration mismatch between {sides[0]} and {sides[1]}: {details}. "
            f"Views made under one configuration are not what a model trained under the other expects."
        )


def rig_config_path(name_or_path: str | Path) -> Path:
    """A rig name (``ring5``) -> its bundled YAML; a path (``*.yaml``, or containing a folder) as given."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or len(path.parts) > 1:
        return path
    bundled = CONFIG_DIR / f"{name_or_path}.yaml"
    if not bundled.exists():
        known = sorted(p.stem for p in CONFIG_DIR.glob("*.yaml"))
        raise FileNotFoundError(f"no perception configuration for rig '{name_or_path}' (known rigs: {known})")
    return bundled


def load_perception_config(name_or_path: str | Path) -> PerceptionConfig:
    """The configuration of a rig name (``ring5``, ``azure_kinect``) or of a YAML file."""
    return load_yaml_config(PerceptionConfig, rig_config_path(name_or_path))


def save_perception_config(config: PerceptionConfig, path: str | Path) -> None:
    """Write a YAML that :func:`load_perception_config` reads back to an equal configuration."""
    Path(path).write_text(yaml.safe_dump(config.to_dict(), sort_keys=False))
