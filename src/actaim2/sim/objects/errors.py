"""The one error type of object loading, shared by the folder reader, the hull cache and the loader."""
from __future__ import annotations


class ObjectLoadError(ValueError):
    """An object folder that cannot be loaded (missing, no URDF, bad URDF, missing mesh...): the
    message says which file and why, so a service can answer it instead of crashing."""
