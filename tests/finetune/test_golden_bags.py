"""`actaim2 bag2dataset` on the committed golden bags (bags/sim_azure_kinect_{pull,push}: sim_node with SAPIEN
pictures, control_node, scripted_teleop and bag_recorder split by episode, as a teleop session records):
keyframes and observations checked against the bags read by rosbags' AnyReader (code we did not write)."""
from __future__ import annotations

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from actaim2.data.encoder import ImageEncoder
from actaim2.data.labelling import EMBEDDINGS_FILE
from actaim2.data.storage import DatasetReader
from actaim2.finetune.bag2dataset import bags_to_dataset
from actaim2.perception.config import load_perception_config
from harness import REPO

GOLDEN = [REPO / "bags" / "sim_azure_kinect_pull", REPO / "bags" / "sim_azure_kinect_push"]
LABELS = ["pull", "push"]


def stamp(msg) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def bag_content(path):
    """Keyposes, START/END stamps and (stamp, z image) of every cloud, read without our bag code."""
    out = {"keyposes": [], "clouds": [], "episode": []}
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for connection, _, raw in reader.messages():
            if connection.topic not in ("/keypose", "/points2", "/episode"):
                continue
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.topic == "/keypose":
                p, q = msg.pose.position, msg.pose.orientation
                out["keyposes"].append((msg.phase, [p.x, p.y, p.z], [q.x, q.y, q.z, q.w], msg.gripper_closed, stamp(msg)))
            elif connection.topic == "/episode":
                out["episode"].append((msg.event, stamp(msg), msg.success))
            else:
                points = np.frombuffer(bytes(msg.data), np.float32).reshape(msg.height, msg.width, msg.point_step // 4)
                out["clouds"].append((stamp(msg), points[..., 2].copy()))
    return out


@pytest.fixture(scope="module")
def golden(tmp_path_factory):
    """(dataset, conversion summary, encoder file) of the two golden bags."""
    import torch

    for bag in GOLDEN:
        assert (bag / "metadata.yaml").exists(), f"{bag} is missing (scripts/record_golden_bags.sh records it)"
    root = tmp_path_factory.mktemp("golden")
    torch.manual_seed(0)
    ImageEncoder.autoencoder().save(root / "encoder.pt")
    summary = bags_to_dataset(GOLDEN, root / "demos", load_perception_config("azure_kinect"), "kinova_j2s6s200",
                              root / "encoder.pt")
    return root / "demos", summary, root / "encoder.pt"


def test_golden_bags_give_their_keyposes_and_the_clouds_stamped_before_them(golden):
    out, summary, _ = golden
    reader = DatasetReader(out)
    assert summary["trajectories"] == 2 and summary["bags_with_problems"] == 0
    assert summary["intrinsics_residual_px"]["max"] < 0.5  # SAPIEN's depth: nearly a pinhole
    for entry, bag, label in zip(reader.entries, GOLDEN, LABELS):
        content = bag_content(bag)
        trajectory = reader.read(entry)
        assert entry["mode_label"] == label and entry["label"] == content["episode"][-1][2]
        assert [(k.phase, k.position.tolist(), k.quat_xyzw.tolist(), k.gripper_closed) for k in trajectory.keyposes] == \
            [k[:4] for k in content["keyposes"]]
        (_, start, _), (_, end, _) = content["episode"]
        clouds = [(t, z) for t, z in content["clouds"] if start <= t <= end]
        moments = {f"o{k[0]}": k[4] for k in content["keyposes"]} | {"final": end}
        expected = {"init": clouds[0]}
        for name, moment in moments.items():
            before = [c for c in clouds if c[0] <= moment]
            expected[name] = before[-1] if before else clouds[0]  # INIT marked at START: the first cloud
        for name, (t, z) in expected.items():
            picture = trajectory.observations[name]["azure_kinect"]
            assert trajectory.info["cloud_stamps_ns"][name]["azure_kinect"] == t
            depth = np.nan_to_num(z)
            same = np.isclose(picture.depth, depth, rtol=0.0, atol=0.0005 + 1e-6)
            if name in ("init", "final"):
                # the arm, removed by the self-filter: seen, but a small part of the picture; its pixels
                # are empty or hold what the other robot-hidden observation saw there
                other = np.nan_to_num(expected["final" if name == "init" else "init"][1])
                changed = ~same
                assert 500 < changed.sum() < 0.15 * (depth > 0).sum(), changed.sum()
                from_other = np.isclose(picture.depth, other, rtol=0.0, atol=0.0005 + 1e-6) & (other > 0)
                assert np.all((picture.depth[changed] == 0) | from_other[changed])
                assert from_other[changed].any()  # the arm moved between START and END: some pixels were filled
            else:
                assert same.all()


def test_golden_embeddings_are_those_of_the_stored_robot_hidden_pictures(golden):
    out, _, encoder_file = golden
    reader = DatasetReader(out)
    encoder = ImageEncoder.load(encoder_file)
    with np.load(out / EMBEDDINGS_FILE) as f:
        z = dict(zip(f["ids"].tolist(), f["z"]))
    for entry in reader.entries:
        trajectory = reader.read(entry)
        init, final = encoder.encode([trajectory.observations["init"], trajectory.observations["final"]])
        np.testing.assert_allclose(z[entry["id"]], init - final, rtol=1e-4, atol=1e-4)  # pictures stored in mm
