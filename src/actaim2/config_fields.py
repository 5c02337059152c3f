"""Configuration dataclasses from mappings and YAML files, checked the same way everywhere.

Every configuration read from YAML or JSON (training, perception, domain randomisation, the
mode selector) refuses unknown keys: a typo must not silently fall back to a default. Each
``from_dict`` calls :func:`check_fields` so that the refusal reads the same everywhere, and a
configuration kept in a YAML file of its own is read by :func:`load_yaml_config`, whose errors
name the file.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import TypeVar

import yaml


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


C = TypeVar("C")


def load_yaml_config(cls: type[C], path: Path) -> C:
    """``cls.from_dict`` (a configuration dataclass's) of the YAML file's mapping; an invalid one
    raises ValueError starting with the path."""
    try:
        return cls.from_dict(yaml.safe_load(Path(path).read_text()))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: {exc}") from exc
