"""URDF preparation for physics-only scenes.

SAPIEN cannot even parse a URDF visual with a ``<material>`` when no render device exists
(it creates a render material on the spot), and a physics-only scene cannot hold visual
shapes anyway. So without a render system the simulator loads a copy of the URDF with the
``<visual>`` elements removed and every mesh path made absolute (the copy lives in a cache
folder, not next to the original). The copy is content-addressed and written atomically, so
concurrent processes share it.
"""
from __future__ import annotations

import hashlib
import os
import xml.etree.ElementTree as ET
from pathlib import Path

from actaim2.robots import _resolve_package_uri


def physics_only_urdf(urdf_path: Path, package_dirs: tuple[Path, ...] = (), cache_dir: Path | None = None) -> Path:
    """Path of a visual-free copy of ``urdf_path`` with absolute mesh paths."""
    urdf_path = Path(urdf_path)
    root = ET.parse(urdf_path).getroot()
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    for mesh in root.iter("mesh"):
        mesh.set("filename", _resolve_package_uri(mesh.get("filename", ""), tuple(package_dirs), urdf_path.parent))
    text = '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode")
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    if cache_dir is None:
        cache_dir = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "actaim2" / "urdf"
    path = Path(cache_dir) / f"{urdf_path.stem}-physics-{digest}.urdf"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, path)
    return path
