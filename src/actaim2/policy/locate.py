"""Where a checkpoint is: a path to its stem (or to its .json / .safetensors), or a name looked up
in checkpoint folders: the installed ``share/actaim2_policy/checkpoints``, where the committed
checkpoints (``actaim2_policy/checkpoints/``) are installed."""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Sequence

from actaim2.artifact.checkpoint import paths

COMMITTED = "actaim2_ring5"  # the committed ring5 checkpoint: policy_node's default, the demo's


def installed_folders() -> list[Path]:
    """share/actaim2_policy/checkpoints of the installed ROS package (none outside a ROS workspace)."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError:
        return []
    try:
        return [Path(get_package_share_directory("actaim2_policy")) / "checkpoints"]
    except PackageNotFoundError:
        return []


def resolve_checkpoint(name_or_path: str | Path, search_dirs: Sequence[Path] = ()) -> Path:
    """The checkpoint's stem; FileNotFoundError listing every place looked at."""
    given = Path(name_or_path).expanduser()
    if not str(name_or_path):
        raise FileNotFoundError("no checkpoint given")
    is_name = len(given.parts) == 1 and given.suffix not in (".json", ".safetensors")
    candidates = ([Path(d) / given for d in search_dirs] if is_name else []) + [given]
    for stem in candidates:
        if paths(stem)[1].is_file():
            return paths(stem)[1].with_suffix("")
    looked = ", ".join(str(paths(c)[1]) for c in candidates)
    raise FileNotFoundError(f"checkpoint '{name_or_path}' not found (looked for {looked})")


def _phases(lineage: dict) -> str:
    return ", ".join(lineage.get("phases_done") or []) or "none"


def describe(stem: Path) -> str:
    """What a checkpoint is, from its JSON alone: path, weights digest, perception digest, training phases.

    A run continued from another (``--init-from``) names the runs it continued, newest first: its
    own phases alone would hide how the rest was trained.
    """
    meta = json.loads(paths(stem)[1].read_text())
    lineage = meta.get("lineage", {})
    phases = _phases(lineage) if lineage.get("phases_done") else "none (untrained)"
    parent = lineage.get("init_from")
    while parent:
        phases += f"; continued from {str(parent.get('weights_sha256'))[:8]} (phases: {_phases(parent)})"
        parent = parent.get("init_from")
    return (f"{stem} (weights sha256 {str(meta.get('weights_sha256'))[:16]}, perception configuration "
            f"{meta.get('perception', {}).get('digest')}, trained phases: {phases})")


def main(argv: list[str]) -> int:
    """``python -m actaim2.policy.locate [NAME_OR_PATH]``: the checkpoint policy_node would load
    (default: the committed one), described; exit code 1 with the reason when there is none."""
    try:
        print(describe(resolve_checkpoint(argv[0] if argv else COMMITTED, installed_folders())))
    except (FileNotFoundError, ValueError) as exc:
        print(exc)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
