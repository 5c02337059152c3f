"""YAML text laid out the way rosbag2's yaml-cpp emitter writes metadata.yaml.

Readers only need valid YAML, but people diff our metadata.yaml against one from `ros2 bag
record`; writing the same layout (two-space maps, sequences indented under their key, ``""``
for empty strings, ``~`` for null, no final newline) makes that diff show only real
differences. tests/bags/test_metadata.py re-emits the Jazzy reference files byte for byte.
"""
from __future__ import annotations

import json
from typing import Any

import yaml

_SPECIAL_START = set("-?:,[]{}#&*!|>'\"%@`")


def scalar(value: Any) -> str:
    if value is None:
        return "~"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return value if _plain_is_safe(value) else json.dumps(value)
    raise TypeError(f"cannot emit {type(value).__name__} {value!r} as a YAML scalar")


def _plain_is_safe(text: str) -> bool:
    """A plain (unquoted) scalar that reads back as this very string."""
    if not text or text != text.strip() or text[0] in _SPECIAL_START:
        return False
    if any(c in text for c in "\n\t\\\"") or ": " in text or " #" in text or text.endswith(":"):
        return False
    try:
        return yaml.safe_load(text) == text
    except yaml.YAMLError:
        return False


def _block(value: Any, indent: int, lines: list[str], first_prefix: str | None = None) -> None:
    """Emit a map or sequence at ``indent``; ``first_prefix`` replaces the first line's padding
    (the "- " of a sequence item that holds this map)."""
    pad = " " * indent
    items = list(value.items()) if isinstance(value, dict) else list(value)
    for number, item in enumerate(items):
        lead = first_prefix if (number == 0 and first_prefix is not None) else pad
        if isinstance(value, dict):
            key, child = item
            if isinstance(child, (dict, list)):
                if not child:
                    lines.append(f"{lead}{key}:")
                    lines.append(" " * (indent + 2) + ("{}" if isinstance(child, dict) else "[]"))
                else:
                    lines.append(f"{lead}{key}:")
                    _block(child, indent + 2, lines)
            else:
                lines.append(f"{lead}{key}: {scalar(child)}")
        else:
            if isinstance(item, dict) and item:
                _block(item, indent + 2, lines, first_prefix=f"{lead}- ")
            elif isinstance(item, (dict, list)):
                raise ValueError("nested sequences and empty maps in sequences are not used by rosbag2 metadata")
            else:
                lines.append(f"{lead}- {scalar(item)}")


def dump(document: dict | list, final_newline: bool = False) -> str:
    """``document`` as block YAML (a list at the top level is how MCAP channels carry QoS)."""
    if not document:
        return ("{}" if isinstance(document, dict) else "[]") + ("\n" if final_newline else "")
    lines: list[str] = []
    _block(document, 0, lines)
    return "\n".join(lines) + ("\n" if final_newline else "")
