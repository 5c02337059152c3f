"""Where a checkpoint is: a path to its stem (or to its .json / .safetensors), or a name looked up
in checkpoint folders: the installed ``share/actaim2_policy/checkpoints``, where the committed
checkpoints (``actaim2_policy/checkpoints/``) are installed."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from actaim2.train.checkpoint import paths

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
