"""Choosing how cameras are rendered: SAPIEN (Vulkan/lavapipe) or Open3D ray casting.

``auto`` takes SAPIEN whenever a Vulkan device can be created and falls back to ray casting
otherwise; ``sapien`` and ``raycast`` force one path (tests exercise both). The choice also
decides how the scene is built: a SAPIEN scene with a render system only exists when a device
does, and a scene without one cannot hold visual shapes - so the scene builder asks
:func:`resolve_render_path` first and passes the answer to :func:`make_renderer`.
"""
from __future__ import annotations

import functools
import logging

import sapien

from actaim2.sim.cameras import CameraSpec
from actaim2.sim.render_raycast import RaycastRenderer
from actaim2.sim.render_sapien import SHADER, SapienRenderer

RENDER_PATHS = ("auto", "sapien", "raycast")
Renderer = SapienRenderer | RaycastRenderer

log = logging.getLogger(__name__)


@functools.cache
def vulkan_device_error() -> str | None:
    """None when SAPIEN can create a render device here, else SAPIEN's reason (cached)."""
    try:
        sapien.render.RenderSystem()
    except RuntimeError as exc:
        return str(exc)
    return None


def resolve_render_path(requested: str = "auto") -> str:
    """``sapien`` or ``raycast`` for a requested path; logs which one is in use and why.

    Raises ValueError for an unknown name, and RuntimeError when ``sapien`` is forced but no
    Vulkan device exists (silently degrading a forced choice would hide a broken setup).
    """
    if requested not in RENDER_PATHS:
        raise ValueError(f"unknown render path '{requested}': use one of {RENDER_PATHS}")
    if requested == "raycast":
        log.info("render path: raycast (Open3D ray casting of collision meshes, flat colours), as requested")
        return "raycast"
    error = vulkan_device_error()
    if error is None:
        log.info("render path: sapien (Vulkan rasteriser, shader %s)", SHADER)
        return "sapien"
    if requested == "sapien":
        raise RuntimeError(
            f"render path 'sapien' requested but no Vulkan device: {error} (set VK_ICD_FILENAMES, see scripts/env.sh)"
        )
    log.warning("render path: raycast (no Vulkan device: %s); colours are flat per link", error)
    return "raycast"


def make_renderer(path: str, scene: sapien.Scene, cameras: list[CameraSpec]) -> Renderer:
    """The renderer of a resolved path (``sapien`` needs a scene with a render system)."""
    if path == "sapien":
        return SapienRenderer(scene, cameras)
    if path == "raycast":
        return RaycastRenderer(scene, cameras)
    raise ValueError(f"render path must be resolved to 'sapien' or 'raycast', got '{path}'")
