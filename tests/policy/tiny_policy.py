"""A small real checkpoint for the policy tests, trained in seconds through the training API.

The perception configuration is ring5's at 64 px (written to a YAML that fusion_node and
policy_node both load, so their digests agree). The training views are the real ones of the
test scene (storage_furniture 0, SimEnv with the ray-cast renderer, robot hidden, rendered by
the same Perception code fusion_node runs), with noise added and random task embeddings, so the
predictor learns one thing: the phase -> a fixed, reachable keypose in front of the cabinet
(approach along +x, close the gripper, pull back; checked with the control library's planner). The episodes it drives through the node graph therefore
run all four phases, MANIPULATE included, whatever eps the barely-trained selector samples.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from actaim2.artifact.checkpoint import perception_record
from actaim2.models.obs_encoder import ObsEncoderConfig
from actaim2.models.selector_base import SelectorConfig
from actaim2.models.view_geometry import CubePlacement
from actaim2.perception.config import (
    PerceptionConfig,
    load_perception_config,
    save_perception_config,
)
from actaim2.perception.fusion import CameraCloud
from actaim2.perception.pipeline import Perception
from actaim2.train.config import PhaseConfig, TrainConfig
from actaim2.train.data import TrainingData
from actaim2.train.distributed import init_distributed
from actaim2.train.loop import POLICY, Trainer

SCENE = {"category": "storage_furniture", "instance": 0}
RESOLUTION = 64
Z_DIM = 20
QUAT_PLUS_X = [0.0, np.sqrt(0.5), 0.0, np.sqrt(0.5)]  # tcp z (approach) along world +x, fingers closing along y
# INIT, REACH, GRASP, MANIPULATE in free space 5-8 cm in front of the drawer handle (x 0.48-0.52 m with the
# seed's placement), far enough from the base for the straight REACH line: every phase executes for any seed.
TARGETS = np.array([[0.36, 0.0, 0.50, *QUAT_PLUS_X, 0.0],
                    [0.44, 0.0, 0.50, *QUAT_PLUS_X, 0.0],
                    [0.44, 0.0, 0.50, *QUAT_PLUS_X, 1.0],
                    [0.34, 0.0, 0.50, *QUAT_PLUS_X, 1.0]], np.float32)
CONFIG = TrainConfig(
    phases=("selector", "predictor"),
    selector=SelectorConfig(z_tokens=4, clusters=4, width=32, blocks=1, decoder_layers=1, latent_dim=8, y_dim=8,
                            obs=ObsEncoderConfig(input_resolution=16, widths=(8, 16), token_dim=16)),
    predictor=dict(patch=8, width=32, layers_within=1, layers_across=1, heads=2, dropout=0.0),
    selector_phase=PhaseConfig(epochs=2, batch_size=8, lr=1e-3),
    predictor_phase=PhaseConfig(epochs=40, batch_size=8, lr=2e-3, warmup_fraction=0.02),
    augment=False, validation_fraction=0.0, checkpoint_minutes=1e9, log_every=10_000,
)


def test_perception_config() -> PerceptionConfig:
    return load_perception_config("ring5").replace(resolution=RESOLUTION)


def scene_views(config: PerceptionConfig, seeds: tuple[int, ...] = (0, 1)) -> np.ndarray:
    """(len(seeds), 5, C, R, R) views of the test scene, robot hidden, as fusion_node renders them."""
    from actaim2.sim.env import SimEnv

    env = SimEnv("panda", cameras="ring5", render_path="raycast")
    perception = Perception(config.replace(remove_robot_views=False))  # the robot is hidden by the renderer here
    out = []
    for seed in seeds:
        env.reset(seed=seed, dof_fraction=0.5, **SCENE)
        obs = env.observe(with_robot=False)
        clouds = [CameraCloud(f.xyz.reshape(-1, 3), f.rgb.reshape(-1, 3), obs.cameras[n].T_world_optical)
                  for n, f in sorted(obs.frames.items())]
        out.append(perception.process(clouds).views)
    return np.stack(out)


@dataclass(frozen=True)
class TinyCheckpoint:
    stem: Path  # the checkpoint (policy.json + policy.safetensors)
    perception_yaml: Path  # its perception configuration, for fusion_node and policy_node
    config: PerceptionConfig
    views: np.ndarray  # (2, 5, C, R, R) float32: the test scene's views (seeds 0 and 1)


def training_data(scenes: np.ndarray, placement: CubePlacement, trajectories: int = 16, seed: int = 0) -> TrainingData:
    """Noisy copies of the scene views, TARGETS as every trajectory's keyposes, random task embeddings."""
    rng = np.random.default_rng(seed)
    views = scenes[np.arange(trajectories) % len(scenes)] + rng.normal(0.0, 0.03, (trajectories, *scenes.shape[1:]))
    views = views.astype(np.float16)
    keyposes = np.repeat(TARGETS[None], trajectories, axis=0)
    gripper = np.repeat(np.array([[False, False, False, True]]), trajectories, axis=0)
    valid = placement.contains(torch.from_numpy(keyposes[..., :3])).numpy()
    z = rng.normal(size=(trajectories, Z_DIM)).astype(np.float32)
    return TrainingData(views, np.repeat(views[:, None], 4, axis=1), keyposes, gripper, valid, z,
                        [f"t{i:03d}" for i in range(trajectories)])


def make_checkpoint(out: Path, trajectories: int = 16, seed: int = 0) -> TinyCheckpoint:
    """Train and save the tiny policy under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    config = test_perception_config()
    yaml_path = out / "perception_ring5_64.yaml"
    save_perception_config(config, yaml_path)
    scenes = scene_views(config)
    placement = CubePlacement.of(config)
    data = training_data(scenes, placement, trajectories, seed)
    torch.manual_seed(seed)
    trainer = Trainer(CONFIG, data, None, placement, perception_record(config), "tiny-synthetic", out,
                      init_distributed("cpu"), show_progress=False)
    trainer.run()
    return TinyCheckpoint(out / POLICY, yaml_path, config, scenes.astype(np.float32))


if __name__ == "__main__":  # python tests/policy/tiny_policy.py OUT: a checkpoint for trying the nodes by hand
    import sys

    print(make_checkpoint(Path(sys.argv[1])))
