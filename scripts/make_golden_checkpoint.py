"""Trains the small azure_kinect test checkpoint that policy_node serves in the golden bag replay.

    python scripts/make_golden_checkpoint.py && python tests/bags/golden_policy.py write

(scripts/record_golden_bags.sh runs both after recording the bags.) The checkpoint is
tests/bags/golden/policy_azure_kinect.{json,safetensors}: a test fixture, not a production
checkpoint (none exists for azure_kinect yet); it is under 1 MB.

Why trained (about a minute on 1 CPU thread) rather than left at its random initialisation: the
keypose is decoded by argmax (a fine cell of the cube grid, Euler bins of 5 degrees), and an
untrained network's nearly flat heatmaps and bin logits put near-ties everywhere, so float
differences between CPUs or the replayed views' small differences would flip the answer. Trained
on the bags' own demonstrations, its peaks are sharp and the golden answers are stable.

Training data, from the committed bags (bags/README.md) with the azure_kinect configuration:
per bag, the views fusion_node publishes (actaim2.perception.bag_views), O_init = the first
frame, O_i = the last frame at or before the bag's i-th /keypose (the first frame for INIT,
commanded before any cloud), the four recorded /keyposes as targets, and a fixed random task
embedding per bag (so the selector's eps tells a pull from a push scene); each bag is repeated
``COPIES`` times with Gaussian noise on the views. Seeds are fixed; on one thread the result is
reproducible on one machine (another CPU may round differently: rerun the golden writer then).
"""
from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
BAGS = [ROOT / "bags" / "sim_azure_kinect_pull", ROOT / "bags" / "sim_azure_kinect_push"]
OUT = ROOT / "tests" / "bags" / "golden" / "policy_azure_kinect"
ROBOT = "kinova_j2s6s200"  # the robot the bags were recorded with
PERCEPTION = "azure_kinect"
COPIES = 8  # noisy copies of each bag's trajectory
NOISE = 0.03  # std of the noise added to the views (values normalised to about [-1, 1])
Z_DIM = 8
SEED = 0


def train_config():
    """Tiny sizes: 128 px views in 16 px patches (64 tokens a view), width 32, one block each."""
    from actaim2.models.obs_encoder import ObsEncoderConfig
    from actaim2.models.selector_base import SelectorConfig
    from actaim2.train.config import PhaseConfig, TrainConfig

    return TrainConfig(
        phases=("selector", "predictor"),
        selector=SelectorConfig(z_dim=Z_DIM, z_tokens=4, clusters=4, width=32, blocks=1, decoder_layers=1, latent_dim=8,
                                y_dim=8, obs=ObsEncoderConfig(input_resolution=16, widths=(8, 16), token_dim=16)),
        predictor=dict(patch=16, width=32, layers_within=1, layers_across=1, heads=2, dropout=0.0),
        selector_phase=PhaseConfig(epochs=20, batch_size=8, lr=1e-3),
        predictor_phase=PhaseConfig(epochs=60, batch_size=8, lr=2e-3, warmup_fraction=0.02),
        augment=False, validation_fraction=0.0, checkpoint_minutes=1e9, log_every=10_000,
    )


def bag_keyposes(bag: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(stamps (4,) ns, keyposes (4, 8) [position, quaternion xyzw, gripper], gripper (4,)) of the bag's /keypose, by phase."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    by_phase = {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for connection, _, raw in reader.messages(connections=[c for c in reader.connections if c.topic == "/keypose"]):
            msg = reader.deserialize(raw, connection.msgtype)
            p, q = msg.pose.position, msg.pose.orientation
            stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
            by_phase[int(msg.phase)] = (stamp, [p.x, p.y, p.z, q.x, q.y, q.z, q.w, float(msg.gripper_closed)])
    if sorted(by_phase) != [0, 1, 2, 3]:
        raise ValueError(f"{bag}: /keypose holds phases {sorted(by_phase)}, a demonstration has 0..3")
    stamps = np.array([by_phase[i][0] for i in range(4)], np.int64)
    keyposes = np.array([by_phase[i][1] for i in range(4)], np.float32)
    # the gripper state when O_i was taken: the state the previous keypose left (open before the first)
    gripper = np.concatenate([[False], keyposes[:3, 7] > 0.5])
    return stamps, keyposes, gripper


def training_data(config, rng: np.random.Generator):
    from actaim2.perception.bag_views import bag_frames
    from actaim2.robots import load_robot_spec
    from actaim2.train.data import TrainingData

    robot = load_robot_spec(ROBOT)
    init, key, poses, grippers, z, ids = [], [], [], [], [], []
    for bag in BAGS:
        frames = list(bag_frames(bag, config, robot))
        stamps = np.array([f.stamp_ns for f in frames])
        kp_stamps, keyposes, gripper = bag_keyposes(bag)
        before = [max(int(np.searchsorted(stamps, s, side="right")) - 1, 0) for s in kp_stamps]
        task = rng.normal(size=Z_DIM).astype(np.float32)
        for copy in range(COPIES):
            noisy = lambda v: (v + rng.normal(0.0, NOISE, v.shape)).astype(np.float16)  # noqa: E731
            init.append(noisy(frames[0].views))
            key.append(np.stack([noisy(frames[i].views) for i in before]))
            poses.append(keyposes)
            grippers.append(gripper)
            z.append(task + rng.normal(0.0, 0.05, Z_DIM).astype(np.float32))
            ids.append(f"{bag.name}_{copy}")
    keyposes = np.stack(poses)
    return TrainingData(np.stack(init), np.stack(key), keyposes, np.stack(grippers), np.ones(keyposes.shape[:2], bool),
                        np.stack(z), ids)


def main() -> None:
    from actaim2.artifact.checkpoint import perception_record
    from actaim2.models.view_geometry import CubePlacement
    from actaim2.perception.config import load_perception_config
    from actaim2.train.distributed import init_distributed
    from actaim2.train.loop import POLICY, Trainer

    torch.set_num_threads(1)
    torch.manual_seed(SEED)
    config = load_perception_config(PERCEPTION)
    data = training_data(config, np.random.default_rng(SEED))
    placement = CubePlacement.of(config)
    if not placement.contains(torch.from_numpy(data.keyposes[..., :3])).all():
        raise ValueError("a recorded keypose lies outside the perception cube: it has no heatmap target")
    with tempfile.TemporaryDirectory() as tmp:
        trainer = Trainer(train_config(), data, None, placement, perception_record(config), "golden-bags", Path(tmp),
                          init_distributed("cpu"), show_progress=False)
        results = trainer.run()
        OUT.parent.mkdir(parents=True, exist_ok=True)
        for suffix in (".json", ".safetensors"):
            shutil.copyfile(Path(tmp) / f"{POLICY}{suffix}", OUT.with_suffix(suffix))
    print(f"{OUT}: {sum(OUT.with_suffix(s).stat().st_size for s in ('.json', '.safetensors')) / 1e3:.0f} kB; {results}")


if __name__ == "__main__":
    sys.exit(main())
