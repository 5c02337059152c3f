"""The import graph follows the layers (actaim2.tools.layers), and the check finds what breaks them."""
from __future__ import annotations

from pathlib import Path

from actaim2.tools.layers import main


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def test_the_repository_follows_its_layers(capsys):
    assert main([]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "artifact -> models" in out and "actaim2_ros -> " in out


def test_upward_imports_node_package_cross_imports_and_circles_are_found(tmp_path, capsys):
    _write(tmp_path, {
        "src/actaim2/__init__.py": "",
        "src/actaim2/data/__init__.py": "",
        "src/actaim2/data/load.py": "def f():\n    from actaim2.train import loop\n",
        "src/actaim2/train/__init__.py": "",
        "src/actaim2/train/loop.py": "from actaim2.policy.inference import X\n",
        "src/actaim2/policy/__init__.py": "",
        "src/actaim2/policy/inference.py": "X = 1\n",
        "src/actaim2/sim/__init__.py": "",
        "src/actaim2/sim/a.py": "from .b import y\nimport rclpy\n",
        "src/actaim2/sim/b.py": "from . import a\ny = 2\n",
        "actaim2_sim/actaim2_sim/__init__.py": "",
        "actaim2_sim/actaim2_sim/node.py": "from actaim2_perception.codec import to_msg\n",
        "actaim2_perception/actaim2_perception/__init__.py": "",
        "actaim2_perception/actaim2_perception/codec.py": "from actaim2_ros.main import spin\n",
        "actaim2_ros/actaim2_ros/__init__.py": "",
        "actaim2_ros/actaim2_ros/main.py": "import actaim2.sim.a\n",
    })
    assert main(["--repo", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "actaim2.data.load:2: imports actaim2.train.loop: data (data) may only import layers below" in err
    assert "actaim2.train.loop:1: imports actaim2.policy.inference" in err
    assert "actaim2.sim.a:2: imports rclpy: the library imports no ROS package" in err
    assert "actaim2_sim.node:1: imports actaim2_perception.codec: node packages never import each other" in err
    assert "import circle: actaim2.sim.a -> actaim2.sim.b -> actaim2.sim.a" in err
    assert "actaim2_perception.codec:1" not in err  # a node package may import actaim2_ros
