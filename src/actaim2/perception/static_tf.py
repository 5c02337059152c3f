"""A buffer of static transforms that composes chains, standing in for tf2 (not installable here).

/tf_static carries edges ``parent -> child`` (``T_parent_child``). Camera extrinsics typically
arrive as chains such as ``world -> camera_base -> depth_camera_link`` from different
publishers, so lookups search the undirected frame graph and compose (inverting edges walked
backwards). Static edges never expire; a re-published edge replaces the previous one, as in tf2.
The buffer is thread-safe: a ROS callback may add edges while a worker thread looks them up.
"""
from __future__ import annotations

import threading
from collections import deque

import numpy as np

from actaim2.geometry import invert


class UnknownFrameError(LookupError):
    """No chain of static transforms connects the two frames."""


class StaticTransformBuffer:
    """Static transforms keyed by child frame (a frame has exactly one parent, as in tf2)."""

    def __init__(self) -> None:
        self._parent: dict[str, tuple[str, np.ndarray]] = {}
        self._cache: dict[tuple[str, str], np.ndarray] = {}
        self._lock = threading.Lock()

    def set_transform(self, parent: str, child: str, T_parent_child: np.ndarray) -> None:
        """Add or replace the edge parent -> child."""
        T = np.asarray(T_parent_child, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"transform {parent} -> {child} must be a finite 4x4 matrix")
        if parent == child:
            raise ValueError(f"transform from '{parent}' to itself")
        with self._lock:
            self._parent[child] = (parent, T)
            self._cache.clear()

    def frames(self) -> set[str]:
        with self._lock:
            return self._frame_names()

    def _frame_names(self) -> set[str]:
        return set(self._parent) | {p for p, _ in self._parent.values()}

    def can_transform(self, target: str, source: str) -> bool:
        try:
            self.lookup(target, source)
        except UnknownFrameError:
            return False
        return True

    def lookup(self, target: str, source: str) -> np.ndarray:
        """``T_target_source``: maps points expressed in ``source`` into ``target``."""
        if target == source:
            return np.eye(4)
        key = (target, source)
        with self._lock:
            if key not in self._cache:
                self._cache[key] = self._search(target, source)
            return self._cache[key]

    def _search(self, target: str, source: str) -> np.ndarray:
        neighbours: dict[str, list[tuple[str, np.ndarray]]] = {}
        for child, (parent, T) in self._parent.items():
            # Edge child -> parent carries T_parent_child; walking parent -> child needs its inverse.
            neighbours.setdefault(child, []).append((parent, T))
            neighbours.setdefault(parent, []).append((child, invert(T)))
        # Breadth-first from source; T_frame_source accumulates along the path.
        reached = {source: np.eye(4)}
        queue = deque([source])
        while queue:
            frame = queue.popleft()
            for other, T_other_frame in neighbours.get(frame, []):
                if other not in reached:
                    reached[other] = T_other_frame @ reached[frame]
                    if other == target:
                        return reached[other]
                    queue.append(other)
        known = ", ".join(sorted(self._frame_names())) or "none"
        raise UnknownFrameError(f"no static transform chain from '{source}' to '{target}' (known frames: {known})")
