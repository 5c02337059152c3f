"""Node graphs: one node list (``graphs.yaml``) that makes both a ROS 2 XML launch file and the
command lines ``actaim2 launch`` starts, so the two cannot drift apart.

A graph file maps a graph name to its nodes::

    sim_panda_ring5:
      description: simulated Panda, five ring cameras, learned policy
      nodes:
        - package: actaim2_sim
          executable: sim_node
          params_files: [actaim2_sim/config/sim_node.yaml]   # <package>/<path inside its share folder>
          parameters: {robot: panda, rig: ring5}            # override the files, as -p name:=value
                                                            # ($(find-pkg-share <package>) is expanded)
          remappings: {/points2: /camera/points2}           # from: to
        - package: actaim2_policy
          executable: viz_node
          if: viz                                           # only when the argument viz is true
      arguments: {viz: false}                               # launch arguments and their defaults

Parameter files are named ``<package>/<path>`` and resolved in that package's share folder
(``$(find-pkg-share <package>)/<path>`` in the XML), so the same list works on a ROS 2 install,
in this workspace and from a clone.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree

import yaml

# Every process of a graph stays on this machine (the project's DDS default; nodes set it too).
GRAPH_ENVIRONMENT = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}


class GraphError(ValueError):
    """A graph file or graph name that cannot be used; the message says which and why."""


@dataclass(frozen=True)
class NodeSpec:
    package: str
    executable: str
    name: str
    params_files: tuple[str, ...] = ()
    parameters: dict[str, object] = field(default_factory=dict)
    remappings: dict[str, str] = field(default_factory=dict)
    condition: str = ""  # the launch argument that must be true for the node to start; "" = always

    def ros_args(self, share_dir) -> list[str]:
        """The ``--ros-args`` part of ``ros2 run`` for this node; ``share_dir(package)`` finds a
        package's share folder."""
        args = ["--ros-args", "-r", f"__node:={self.name}"]
        for ref in self.params_files:
            package, _, relative = ref.partition("/")
            args += ["--params-file", str(Path(share_dir(package)) / relative)]
        for key, value in self.parameters.items():
            args += ["-p", f"{key}:={expand_share(format_value(value), share_dir)}"]
        for source, target in self.remappings.items():
            args += ["-r", f"{source}:={target}"]
        return args


@dataclass(frozen=True)
class Graph:
    name: str
    description: str
    nodes: tuple[NodeSpec, ...]
    arguments: dict[str, bool] = field(default_factory=dict)  # launch argument -> default

    def started(self, values: dict[str, bool]) -> tuple[NodeSpec, ...]:
        """The nodes that start with the launch arguments ``values`` (defaults for the others)."""
        unknown = sorted(set(values) - set(self.arguments))
        if unknown:
            raise GraphError(f"graph {self.name} has no argument(s) {unknown}; "
                             f"arguments: {sorted(self.arguments) or 'none'}")
        chosen = {**self.arguments, **values}
        return tuple(n for n in self.nodes if not n.condition or chosen[n.condition])


def parse_arguments(texts: list[str]) -> dict[str, bool]:
    """``name:=true|false`` launch arguments as ``ros2 launch`` takes them."""
    values = {}
    for text in texts:
        name, sep, value = text.partition(":=")
        if not sep or value.lower() not in ("true", "false"):
            raise GraphError(f"launch argument '{text}' is not name:=true or name:=false")
        values[name] = value.lower() == "true"
    return values


def expand_share(text: str, share_dir) -> str:
    """``$(find-pkg-share <package>)`` replaced by the package's share folder, as ros2 launch does."""
    while "$(find-pkg-share " in text:
        start = text.index("$(find-pkg-share ")
        end = text.index(")", start)
        text = text[:start] + str(share_dir(text[start + len("$(find-pkg-share "):end].strip())) + text[end + 1:]
    return text


def format_value(value: object) -> str:
    """A parameter value as ROS parses it on the command line and in launch XML (YAML syntax)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(format_value(v) for v in value) + "]"
    return str(value)


def load_graphs(path: Path) -> dict[str, Graph]:
    """Every graph of a graphs YAML file, validated (unknown keys and duplicate node names refused)."""
    try:
        raw = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as error:
        raise GraphError(f"cannot read graph file {path}: {error}") from error
    if not isinstance(raw, dict):
        raise GraphError(f"{path}: expected a mapping of graph name -> graph")
    graphs = {}
    for name, body in raw.items():
        nodes = []
        for k, entry in enumerate((body or {}).get("nodes", [])):
            unknown = set(entry) - {"package", "executable", "name", "params_files", "parameters",
                                    "remappings", "if"}
            if unknown or not {"package", "executable"} <= set(entry):
                raise GraphError(f"{path}: graph {name} node {k}: needs package and executable; unknown keys {sorted(unknown)}")
            nodes.append(NodeSpec(entry["package"], entry["executable"], entry.get("name", entry["executable"]),
                                  tuple(entry.get("params_files", ())), dict(entry.get("parameters") or {}),
                                  dict(entry.get("remappings") or {}), str(entry.get("if", ""))))
        arguments = {str(k): bool(v) for k, v in ((body or {}).get("arguments") or {}).items()}
        undeclared = sorted({n.condition for n in nodes if n.condition} - set(arguments))
        if undeclared:
            raise GraphError(f"{path}: graph {name}: nodes depend on undeclared argument(s) "
                             f"{undeclared}")
        names = [n.name for n in nodes]
        if len(set(names)) != len(names):
            raise GraphError(f"{path}: graph {name} has duplicate node names: {names}")
        description = str((body or {}).get("description", ""))
        graphs[name] = Graph(name, description, tuple(nodes), arguments)
    return graphs


def to_launch_xml(graph: Graph) -> str:
    """The graph as a ROS 2 XML launch file (``ros2 launch <file>`` on a real install)."""
    root = ElementTree.Element("launch")
    root.append(ElementTree.Comment(f" {graph.name}: {graph.description} "
                                    "(generated from graphs.yaml beside this file, whose header says how: edit that, not this) "))
    for key, value in graph.arguments.items():
        ElementTree.SubElement(root, "arg", name=key, default=format_value(value))
    for key, value in GRAPH_ENVIRONMENT.items():
        ElementTree.SubElement(root, "set_env", name=key, value=value)
    for spec in graph.nodes:
        node = ElementTree.SubElement(root, "node", pkg=spec.package, exec=spec.executable, name=spec.name, output="screen")
        if spec.condition:
            node.set("if", f"$(var {spec.condition})")
        for ref in spec.params_files:
            package, _, relative = ref.partition("/")
            ElementTree.SubElement(node, "param", {"from": f"$(find-pkg-share {package})/{relative}"})
        for key, value in spec.parameters.items():
            ElementTree.SubElement(node, "param", name=key, value=format_value(value))
        for source, target in spec.remappings.items():
            ElementTree.SubElement(node, "remap", {"from": source, "to": target})
    ElementTree.indent(root, space="  ")
    return ElementTree.tostring(root, encoding="unicode") + "\n"


def parse_launch_xml(text: str) -> list[NodeSpec]:
    """The nodes a launch XML file starts (what a test compares with :func:`load_graphs`)."""
    nodes = []
    for node in ElementTree.fromstring(text).iter("node"):
        files, parameters = [], {}
        for param in node.iter("param"):
            if "from" in param.attrib:
                package, relative = param.attrib["from"].removeprefix("$(find-pkg-share ").split(")/", 1)
                files.append(f"{package}/{relative}")
            else:
                parameters[param.attrib["name"]] = param.attrib["value"]
        remaps = {r.attrib["from"]: r.attrib["to"] for r in node.iter("remap")}
        condition = node.attrib.get("if", "").removeprefix("$(var ").removesuffix(")")
        nodes.append(NodeSpec(node.attrib["pkg"], node.attrib["exec"], node.attrib["name"],
                              tuple(files), parameters, remaps, condition))
    return nodes
