"""Parsing a URDF into SAPIEN articulation builders, with or without its visuals.

SAPIEN cannot even parse a URDF visual with a ``<material>`` when no render device exists
(it creates a render material on the spot), and a physics-only scene cannot hold visual
shapes anyway. So without a render system the loader reads a copy of the URDF with the
``<visual>`` elements removed and every mesh path made absolute, written once per content
(:func:`actaim2.robots.write_cached_urdf`); meshes are read from their originals.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import sapien

from actaim2.robots import resolve_package_uri, write_cached_urdf


def parse_urdf(loader: sapien.wrapper.urdf_loader.URDFLoader, urdf_path: Path, srdf_path: Path | None = None,
               package_dirs: tuple[Path, ...] = (), keep_visuals: bool = True):
    """``loader.parse`` of ``urdf_path`` (articulation builders, free-body builders, cameras);
    ``keep_visuals=False`` parses it without visuals (see the module docstring)."""
    srdf = str(srdf_path) if srdf_path is not None else ""  # "" = no SRDF (SAPIEN would guess a path)
    if keep_visuals:
        return loader.parse(str(urdf_path), srdf_file=srdf)
    urdf_path = Path(urdf_path)
    root = ET.parse(urdf_path).getroot()
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    for mesh in root.iter("mesh"):
        mesh.set("filename", resolve_package_uri(mesh.get("filename", ""), tuple(package_dirs), urdf_path.parent))
    return loader.parse(str(write_cached_urdf(root, f"{urdf_path.stem}-physics")), srdf_file=srdf)
