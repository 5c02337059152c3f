"""`python -m actaim2.tools.layers`: the import graph of the library's packages and of the ROS
packages, checked against the layer order; exit code 1 when an import breaks it.

Inside ``src/actaim2`` a package imports only packages of lower layers (:data:`LAYERS`, lowest
first). Above the policy artifact the layers fork into two branches that never import each
other: training (``train``, then ``finetune``) writes policy artifacts, serving (``policy``, then
``eval``) reads them. The library imports no ROS package. A ROS node package imports the
library, ``actaim2_ros`` and message packages, never another node package. Every import counts,
also one inside a function or under ``TYPE_CHECKING``, and no module may reach itself through
imports (an import circle).
"""
from __future__ import annotations

import argparse
import ast
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

LIBRARY = "actaim2"
ROS_GLUE = "actaim2_ros"
NODE_PACKAGES = ("actaim2_control", "actaim2_perception", "actaim2_policy", "actaim2_sim")
ROS_CLIENT = "rclpy"
TRAINING, SERVING = "training", "serving"


@dataclass(frozen=True)
class Layer:
    name: str
    packages: tuple[str, ...]  # top-level modules and packages of actaim2
    branch: str | None = None  # TRAINING or SERVING above the artifact; None: shared by both


# Lowest first. A package may import the packages of the layers below its own, except those of
# the other branch.
LAYERS = (
    Layer("foundations", ("config_fields", "geometry", "keypose", "metrics", "parallel", "profiling", "progress",
                          "robots", "runtime", "stamps")),
    Layer("presets", ("gripper", "launch")),
    Layer("world", ("bags", "control", "perception", "sim")),
    Layer("rollouts", ("rollout",)),
    Layer("data", ("data",)),
    Layer("models", ("models",)),
    Layer("artifact", ("artifact", "protocol")),
    Layer("training", ("train",), TRAINING),
    Layer("serving", ("policy",), SERVING),
    Layer("fine-tuning", ("finetune",), TRAINING),
    Layer("evaluation", ("eval",), SERVING),
    Layer("records", ("report",)),
    Layer("commands", ("bench", "cli", "export", "tools", "viz")),
)


@dataclass(frozen=True)
class Import:
    source: str  # the importing module, dotted
    target: str  # the imported module, dotted (as far as it exists)
    line: int


def module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def read_imports(roots: list[Path]) -> tuple[list[Import], set[str]]:
    """Every import statement of the Python files below each of ``roots`` (a folder whose
    subfolders are importable packages), with relative imports resolved; and the modules found."""
    files = {module_name(f, root): f for root in roots for f in sorted(root.glob("*/**/*.py"))
             if f.relative_to(root).parts[0] not in ("test", "tests")}
    imports = []
    for module, path in files.items():
        package_parts = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    kept = package_parts[:len(package_parts) - node.level + 1]
                    base = ".".join(kept + ([node.module] if node.module else []))
                names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in files else base for alias in node.names]
            else:
                continue
            for name in names:
                imports.append(Import(module, _existing(name, files), node.lineno))
    return imports, set(files)


def _existing(name: str, modules: dict[str, Path] | set[str]) -> str:
    """``name`` cut back to the longest prefix that is a module found (itself when none is)."""
    parts = name.split(".")
    for end in range(len(parts), 0, -1):
        if ".".join(parts[:end]) in modules:
            return ".".join(parts[:end])
    return name


def library_package(module: str) -> str | None:
    """The top-level package of ``actaim2`` a module belongs to; None outside the library."""
    parts = module.split(".")
    if parts[0] != LIBRARY:
        return None
    return parts[1] if len(parts) > 1 else LIBRARY


def problems(imports: list[Import], modules: set[str]) -> list[str]:
    """Each import that runs against the layer order, crosses node packages or closes a circle."""
    rank = {package: (i, layer) for i, layer in enumerate(LAYERS) for package in layer.packages}
    found = []
    for imp in imports:
        where = f"{imp.source}:{imp.line}: imports {imp.target}"
        top, target_top = imp.source.split(".")[0], imp.target.split(".")[0]
        if top == LIBRARY:
            src, dst = library_package(imp.source), library_package(imp.target)
            if target_top in (ROS_CLIENT, ROS_GLUE, *NODE_PACKAGES) or target_top.endswith("_msgs"):
                found.append(f"{where}: the library imports no ROS package")
            elif dst is not None and src != dst and src != LIBRARY:
                found += _layer_problem(where, src, dst, rank)
        elif top in NODE_PACKAGES and target_top in NODE_PACKAGES and target_top != top:
            found.append(f"{where}: node packages never import each other (shared code goes to {ROS_GLUE})")
        elif top == ROS_GLUE and target_top in NODE_PACKAGES:
            found.append(f"{where}: {ROS_GLUE} is below every node package")
    found += [f"import circle: {' -> '.join(circle)}" for circle in circles(imports, modules)]
    return found


def _layer_problem(where: str, src: str, dst: str, rank: dict[str, tuple[int, Layer]]) -> list[str]:
    for package in (src, dst):
        if package not in rank:
            return [f"{where}: {package} is in no layer (add it to actaim2.tools.layers.LAYERS)"]
    (src_rank, src_layer), (dst_rank, dst_layer) = rank[src], rank[dst]
    if dst_rank >= src_rank:
        return [f"{where}: {src} ({src_layer.name}) may only import layers below its own, "
                f"and {dst} is in {dst_layer.name}"]
    if src_layer.branch and dst_layer.branch and src_layer.branch != dst_layer.branch:
        return [f"{where}: {src} ({src_layer.branch}) never imports the {dst_layer.branch} branch ({dst})"]
    return []


def circles(imports: list[Import], modules: set[str]) -> list[list[str]]:
    """The module import circles (strongly connected components of more than one module, or a
    module importing itself), each as a path that ends where it starts."""
    graph: dict[str, set[str]] = defaultdict(set)
    for imp in imports:
        if imp.target in modules and imp.target != imp.source:
            graph[imp.source].add(imp.target)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components = []

    def visit(start: str) -> None:
        # Tarjan's algorithm without recursion: (node, its remaining neighbours) frames.
        index[start] = low[start] = len(index)
        stack.append(start)
        on_stack.add(start)
        frames = [(start, iter(sorted(graph[start])))]
        while frames:
            node, neighbours = frames[-1]
            for nxt in neighbours:
                if nxt not in index:
                    index[nxt] = low[nxt] = len(index)
                    stack.append(nxt)
                    on_stack.add(nxt)
                    frames.append((nxt, iter(sorted(graph[nxt]))))
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            else:
                frames.pop()
                if frames:
                    low[frames[-1][0]] = min(low[frames[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        components.append(sorted(component))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return [component + component[:1] for component in components]


def package_graph(imports: list[Import]) -> dict[str, set[str]]:
    """{package: packages it imports}: the library's top-level packages among themselves, and each
    ROS package's imports of the library (one node), of ``actaim2_ros``, of node and message packages."""
    graph: dict[str, set[str]] = defaultdict(set)
    for imp in imports:
        in_library = imp.source.split(".")[0] == LIBRARY
        src = library_package(imp.source) if in_library else imp.source.split(".")[0]
        dst = _graph_node(imp.target, in_library)
        if dst is not None and dst != src and src != LIBRARY:
            graph[src].add(dst)
    return graph


def _graph_node(module: str, from_library: bool) -> str | None:
    """The node of the package graph an imported module counts as; None for third-party modules."""
    top = module.split(".")[0]
    if top == LIBRARY:
        return library_package(module) if from_library else LIBRARY
    if top in (ROS_CLIENT, ROS_GLUE, *NODE_PACKAGES) or top.endswith("_msgs"):
        return top
    return None


def describe(graph: dict[str, set[str]]) -> str:
    """The graph as text: the library's layers lowest first, then the ROS packages."""
    lines = []
    for i, layer in enumerate(LAYERS):
        branch = f" [{layer.branch} branch]" if layer.branch else ""
        lines.append(f"{i:2d} {layer.name}{branch}")
        lines += [f"     {package} -> {' '.join(sorted(graph.get(package, ()))) or '-'}" for package in layer.packages]
    lines.append("ROS packages")
    lines += [f"     {package} -> {' '.join(sorted(graph.get(package, ()))) or '-'}"
              for package in (ROS_GLUE, *NODE_PACKAGES)]
    return "\n".join(lines)


def repository_roots(repo: Path) -> list[Path]:
    """The folders whose subfolders are the packages checked: src/ and each ROS package's folder."""
    return [repo / "src", *(repo / p for p in (ROS_GLUE, *NODE_PACKAGES) if (repo / p).is_dir())]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m actaim2.tools.layers", description=__doc__.split("\n\n")[0])
    parser.add_argument("--repo", type=Path, default=Path(__file__).resolve().parents[3],
                        help="the repository root (default: the one this file is in)")
    args = parser.parse_args(argv)
    imports, modules = read_imports(repository_roots(args.repo))
    print(describe(package_graph(imports)))
    found = problems(imports, modules)
    for problem in found:
        print(problem, file=sys.stderr)
    print(f"{len(found)} problem(s)" if found else "the imports follow the layers")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
