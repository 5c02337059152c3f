"""Node parameters: one table per node (name -> (default, description)), declared by one helper.

Every node keeps its parameters in a table beside its code and ships the same defaults, with
comments for people, in ``<package>/config/<node>.yaml``. :func:`declare_parameters` declares a
table on a node (descriptions, optionally read-only) and returns the values in effect;
:func:`yaml_differences` compares a shipped YAML with its table, so one test keeps every node's
YAML honest.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import yaml
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

ParameterTable = Mapping[str, tuple[Any, str]]


def declare_parameters(node: Node, table: ParameterTable, read_only: bool = False) -> dict[str, Any]:
    """Declare every parameter of ``table`` on the rclpy ``node``; return {name: value in effect}."""
    for name, (default, description) in table.items():
        node.declare_parameter(name, default, ParameterDescriptor(description=description, read_only=read_only))
    return {name: node.get_parameter(name).value for name in table}


def yaml_parameters(path: str | Path, node_name: str) -> dict[str, Any]:
    """The ``ros__parameters`` of ``node_name`` (or of the ``/**`` wildcard) in a ROS parameter file."""
    data = yaml.safe_load(Path(path).read_text()) or {}
    for key in (node_name, f"/{node_name}", "/**"):
        if isinstance(data.get(key), dict) and "ros__parameters" in data[key]:
            return dict(data[key]["ros__parameters"] or {})
    raise ValueError(f"{path}: no ros__parameters for '{node_name}' (nor for '/**')")


def yaml_differences(path: str | Path, node_name: str, table: ParameterTable, overlay: bool = False) -> list[str]:
    """What a parameter file says differently from ``table``: unknown names and, unless it is an
    ``overlay`` (a file loaded after the defaults to change some, e.g. a rig variant), other
    defaults and missing names. ``use_sim_time`` is rclpy's own and always allowed. Numbers
    compare to 1e-9, ints and floats alike (YAML writes 1.0 where a table says 1)."""
    given = yaml_parameters(path, node_name)
    problems = [f"unknown parameter '{n}'" for n in given if n not in table and n != "use_sim_time"]
    if overlay:
        return problems
    for name, (default, _) in table.items():
        if name not in given:
            problems.append(f"'{name}' missing (default {default!r})")
        elif not _same(given[name], default):
            problems.append(f"'{name}': YAML {given[name]!r}, declared {default!r}")
    return problems


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    numbers = (int, float)
    if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool) and not isinstance(b, bool):
        return abs(float(a) - float(b)) <= 1e-9
    return a == b
