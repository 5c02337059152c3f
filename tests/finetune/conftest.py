"""Fixtures of the fine-tuning tests: teleop bags recorded once per session from a simulated rollout,
the encoder E they are embedded with, and their conversion into a dataset.

One torch thread, as in tests/train (tests/torch_threads.py).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest
import torch

from sim_bags import DemoSpec, RecordedDemo, SimTeleop
from torch_threads import one_torch_thread  # noqa: F401  (autouse for this folder)

# two pulls and two pushes, on different drawers and placements
DEMOS = [DemoSpec(0, 1, "pull"), DemoSpec(1, 1, "push"), DemoSpec(2, 0, "pull"), DemoSpec(3, 2, "push")]


@dataclass(frozen=True)
class TeleopRecording:
    bag: Path
    demos: list[RecordedDemo]
    encoder: Path  # an encoder E (the default autoencoder, seeded weights)


@dataclass(frozen=True)
class Conversion:
    recording: TeleopRecording
    dataset: Path
    summary: dict


@pytest.fixture(scope="session")
def teleop_recording(tmp_path_factory) -> TeleopRecording:
    from actaim2.data.encoder import ImageEncoder

    root = tmp_path_factory.mktemp("teleop")
    demos = SimTeleop().record(root / "teleop_bag", DEMOS)
    assert all(d.success for d in demos), [(d.spec, d.success) for d in demos]  # the scripted teleoperator succeeds
    torch.manual_seed(0)
    ImageEncoder.autoencoder().save(root / "encoder.pt")
    return TeleopRecording(root / "teleop_bag", demos, root / "encoder.pt")


@pytest.fixture(scope="session")
def converted(teleop_recording, tmp_path_factory) -> Conversion:
    from actaim2.finetune.bag2dataset import bags_to_dataset
    from actaim2.perception.config import load_perception_config

    out = tmp_path_factory.mktemp("converted") / "demos"
    summary = bags_to_dataset([teleop_recording.bag], out, load_perception_config("azure_kinect"), "kinova_j2s6s200",
                              teleop_recording.encoder)
    return Conversion(teleop_recording, out, summary)
