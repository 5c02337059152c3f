"""Tiny real checkpoints for the evaluation tests, trained in seconds through the training API.

Views are the ring5 configuration's (or another rig's) at 64 px (the shape the evaluation renders
for them); the training set is noise views with task embeddings of the real encoder's size (384
per camera of the rig, so Goal-RVT's goal embeddings fit), and keyposes fixed per phase in front of the workspace:
the predictor learns phase -> keypose, the selector barely anything. What the tests check is
the evaluation machinery on real checkpoints, not the policy's quality.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.data.encoder import ImageEncoder
from actaim2.models.obs_encoder import ObsEncoderConfig
from actaim2.models.selector_base import SelectorConfig
from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.config import load_perception_config
from actaim2.sim.cameras import make_rig
from actaim2.train.config import PhaseConfig, TrainConfig
from actaim2.train.data import TrainingData
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import POLICY, Trainer

RESOLUTION = 64
CLUSTERS = 4
QUAT_PLUS_X = [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)]  # approach along world +x
TARGETS = np.array([[0.30, 0.0, 0.45, *QUAT_PLUS_X, 0.0],
                    [0.38, 0.0, 0.45, *QUAT_PLUS_X, 0.0],
                    [0.38, 0.0, 0.45, *QUAT_PLUS_X, 1.0],
                    [0.24, 0.0, 0.45, *QUAT_PLUS_X, 1.0]], np.float32)
CONFIG = TrainConfig(
    phases=("selector", "predictor"),
    selector=SelectorConfig(z_tokens=4, clusters=CLUSTERS, width=32, blocks=1, decoder_layers=1, latent_dim=8, y_dim=8,
                            obs=ObsEncoderConfig(input_resolution=16, widths=(8, 16), token_dim=16)),
    predictor=dict(patch=16, width=32, layers_within=1, layers_across=1, heads=2, dropout=0.0),
    selector_phase=PhaseConfig(epochs=1, batch_size=8, lr=1e-3),
    predictor_phase=PhaseConfig(epochs=10, batch_size=8, lr=2e-3, warmup_fraction=0.02),
    augment=False, validation_fraction=0.0, checkpoint_minutes=1e9, log_every=10_000,
)


def make_encoder(path: Path) -> Path:
    """An untrained autoencoder E (fixed seed): real code path, dimensions of the default E."""
    torch.manual_seed(0)
    ImageEncoder.autoencoder().save(path)
    return path


def make_checkpoint(out: Path, kind: str = "cgmvae", trajectories: int = 8, seed: int = 0, perception: str = "ring5",
                    clusters: int = CLUSTERS) -> Path:
    """Train a tiny policy with selector ``kind`` (``clusters`` of them) on views of the ``perception`` configuration
    into ``out``; returns its stem (``out/policy``; Goal-RVT: ``out/goal_rvt``)."""
    config = load_perception_config(perception).replace(resolution=RESOLUTION)
    rng = np.random.default_rng(seed)
    views = rng.uniform(0.0, 1.0, (trajectories, 5, len(config.channels), RESOLUTION, RESOLUTION)).astype(np.float16)
    placement = CubePlacement.of(config)
    keyposes = np.repeat(TARGETS[None], trajectories, axis=0)
    gripper = np.repeat(np.array([[False, False, False, True]]), trajectories, axis=0)
    valid = placement.contains(torch.from_numpy(keyposes[..., :3])).numpy()
    cameras = len(make_rig(config.rig, np.asarray(config.center)))
    z = rng.normal(size=(trajectories, cameras * ImageEncoder.autoencoder().dim_per_camera))
    # Unit spread in every dimension: the selector's standardisation (spreads floored at their
    # median) then leaves z as drawn, and the barely trained predictor sees the eps scale it was
    # trained on (with spreads of 0.3-2 from 8 draws, the floor shrank half the dimensions and
    # the 40-step predictor's INIT left the arm's reach).
    z = ((z - z.mean(axis=0)) / z.std(axis=0, ddof=1)).astype(np.float32)
    data = TrainingData(views, np.repeat(views[:, None], 4, axis=1), keyposes, gripper, valid, z,
                        [f"t{i:03d}" for i in range(trajectories)])
    torch.manual_seed(seed)
    train = dataclasses.replace(CONFIG, selector=dataclasses.replace(CONFIG.selector, kind=kind, clusters=clusters))
    Trainer(train, data, None, placement, perception_record(config), "tiny-synthetic", out, init_distributed("cpu"),
            show_progress=False).run()
    return out / POLICY


