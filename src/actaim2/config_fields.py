"""The one check that a mapping names only fields of a configuration dataclass.

Every configuration read from YAML or JSON (training, perception, domain randomisation, the
mode selector) refuses unknown keys: a typo must not silently fall back to a default. Each
``from_dict`` calls :func:`check_fields` so that the refusal reads the same everywhere.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping


def check_fields(cls: type, data: object, where: str) -> None:
    """Raise ValueError unless ``data`` is a mapping whose keys are all fields of dataclass ``cls``.

    ``where`` names the configuration (or the section of one) in the message, which lists the
    unknown keys and the known fields, so the reader sees the typo and its likely correction.
    """
    if not isinstance(data, Mapping):
        raise ValueError(f"{where} must be a mapping, got {type(data).__name__}")
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ValueError(f"unknown {where} field(s) {unknown}; known: {sorted(names)}")
