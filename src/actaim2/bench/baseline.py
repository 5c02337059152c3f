"""An earlier revision's code beside today's, so that a benchmark times both in one run.

Nothing of the old code stays in the tree: it is read from this checkout's git history.

* :func:`modules_at`: modules of a revision loaded into this process under private names; while
  they load, their imports of each other resolve to the revision's versions (any other module
  is today's). The in-process halves of ``bench perception`` time the old path this way.
* :func:`export_tree`: the revision's library and ROS package sources in a folder, and
  :func:`python_path` the ``PYTHONPATH`` that makes a process import them before today's, so a
  node of that revision runs as its own process (``bench perception``'s and ``bench services``'
  node halves).
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
import tarfile
import types
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
BASELINE_REVISION = "4b52758"  # the perception and policy paths before their speed-ups
SOURCES = ("src", "actaim2_perception", "actaim2_policy")  # what export_tree extracts


def source_at(revision: str, path: str) -> str:
    """The text of ``path`` (relative to the repository) at ``revision``; ValueError when git
    cannot show it."""
    shown = subprocess.run(
        ["git", "-C", str(REPO), "show", f"{revision}:{path}"], capture_output=True, text=True
    )
    if shown.returncode != 0:
        raise ValueError(f"git show {revision}:{path} failed: {shown.stderr.strip()}")
    return shown.stdout


def modules_at(revision: str, names: list[str]) -> dict[str, types.ModuleType]:
    """Modules ``names`` (dotted, under ``src/``) as they were at ``revision``, loaded in the given
    order (a module after the ones it imports); today's modules are left in place."""
    loaded: dict[str, types.ModuleType] = {}
    saved = {name: sys.modules.get(name) for name in names}
    try:
        for name in names:
            path = f"src/{name.replace('.', '/')}.py"
            module = types.ModuleType(name)
            module.__file__ = f"{revision}:{path}"
            sys.modules[name] = (
                module  # the later modules' imports of it, and dataclasses, find it
            )
            code = compile(source_at(revision, path), module.__file__, "exec")
            exec(code, module.__dict__)  # noqa: S102 - our own history
            loaded[name] = module
    finally:
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = module
    return loaded


def export_tree(revision: str, folder: Path) -> Path:
    """The revision's :data:`SOURCES` extracted into ``folder``; returns ``folder``."""
    archive = subprocess.run(
        ["git", "-C", str(REPO), "archive", "--format=tar", revision, *SOURCES],
        capture_output=True,
    )
    if archive.returncode != 0:
        raise ValueError(f"git archive {revision} failed: {archive.stderr.decode().strip()}")
    with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
        tar.extractall(folder, filter="data")
    return folder


def python_path(tree: Path) -> str:
    """``PYTHONPATH`` that imports an exported tree's library and node packages before today's
    (the editable install's finder comes after ``sys.path`` entries)."""
    return os.pathsep.join(
        [
            str(tree / "src"),
            *(str(tree / p) for p in SOURCES[1:]),
            os.environ.get("PYTHONPATH", ""),
        ]
    )


def node_command(tree: Path, package: str, executable: str, ros_args: list[str]) -> list[str]:
    """The command line that runs ``package``'s node ``executable`` from an exported tree."""
    return [sys.executable, str(tree / package / package / f"{executable}.py"), *ros_args]
