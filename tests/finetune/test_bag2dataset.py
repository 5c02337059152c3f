"""`actaim2 bag2dataset` on teleop bags made from a simulated rollout of known keyposes (tests/finetune/sim_bags.py):
the keyframes are the marked keyposes with the clouds taken before them, the task embeddings come from
the first and last observations with the robot removed, and bags missing a topic or a keypose are
reported while the rest converts."""
from __future__ import annotations

import json

import numpy as np

from actaim2 import cli
from actaim2.data.encoder import ImageEncoder
from actaim2.data.labelling import EMBEDDINGS_FILE, encoder_digest
from actaim2.data.storage import DatasetReader
from actaim2.data.trajectory import CameraImage
from actaim2.finetune.bag2dataset import fill_robot_pixels
from actaim2.perception.config import capture_part, load_perception_config
from actaim2.sim.cameras import make_rig
from actaim2.sim.env import WORKSPACE_CENTER
from actaim2.sim.sensor_noise import SensorNoise
from sim_bags import rewrite

CAMERA = "azure_kinect"


def test_keyframes_are_the_marked_keyposes_with_the_clouds_taken_before_them(converted):
    reader = DatasetReader(converted.dataset)
    demos = converted.recording.demos
    assert [e["mode_label"] for e in reader.entries] == [d.spec.label for d in demos]
    assert [e["label"] for e in reader.entries] == [True] * len(demos)  # the operator's verdict
    assert all(e["gt_success"] is None and e["sampler"] == "teleop" and e["split"] == "train_seen" for e in reader.entries)
    rig = make_rig("azure_kinect", WORKSPACE_CENTER)[0]
    rendered = SensorNoise.preset("rig", "azure_kinect").camera_geometry(rig)  # the pinhole the sensor model renders
    for entry, demo in zip(reader.entries, demos):
        trajectory = reader.read(entry)
        assert trajectory.object_id == demo.object_id and trajectory.category == "three_drawer_shelf"
        for stored, marked in zip(trajectory.keyposes, demo.keyposes):
            assert stored.to_json() == marked.to_json()
        for name in ("o0", "o1", "o2", "o3", "init", "final"):
            stamp, xyz, rgb, robot, joints = demo.observations[name]
            picture = trajectory.observations[name][CAMERA]
            depth = np.nan_to_num(xyz[..., 2])
            if name.startswith("o"):  # robot visible, exactly the cloud taken before the keypose
                np.testing.assert_allclose(picture.depth, depth, atol=0.0005 + 1e-6)  # stored in millimetres
                np.testing.assert_array_equal(picture.rgb[depth > 0], rgb[depth > 0])
            np.testing.assert_allclose(picture.K, rendered.K, atol=1e-3)
            # the episode's extrinsic, refined from the robot: where /tf_static put the camera (the scene has no
            # calibration error) within what the ray-cast collision hulls' offset from the visual meshes allows
            calibration = trajectory.info["calibration"][CAMERA]
            np.testing.assert_allclose(calibration["nominal_T_world_optical"], rig.T_world_optical, atol=1e-9)
            assert calibration["refined"] and calibration["translation_m"] < 0.006 and calibration["rotation_deg"] < 0.3
            np.testing.assert_allclose(picture.T_world_optical, calibration["T_world_optical"], atol=1e-9)
            assert trajectory.robot_joints[name] == joints
            assert trajectory.info["cloud_stamps_ns"][name][CAMERA] == stamp
    fits = converted.summary["intrinsics_residual_px"]
    assert fits["max"] < 1e-3  # the simulated cloud is a pinhole: range noise moves points along their rays


def test_task_embeddings_come_from_the_first_and_last_observations_with_the_robot_removed(converted):
    """z = E(O_init) - E(O_final), robot removed by the self-filter and its pixels filled from the other
    observation, against the same pictures with the robot's pixels as the renderer's segmentation says."""
    reader = DatasetReader(converted.dataset)
    encoder = ImageEncoder.load(converted.recording.encoder)
    with np.load(converted.dataset / EMBEDDINGS_FILE) as f:
        z = dict(zip(f["ids"].tolist(), f["z"]))
        assert str(f["encoder_digest"]) == encoder_digest(converted.recording.encoder)
    for entry, demo in zip(reader.entries, converted.recording.demos):
        trajectory = reader.read(entry)
        truth, visible, robots = {}, {}, {}
        for name in ("init", "final"):
            _, xyz, rgb, robot, _ = demo.observations[name]
            picture = trajectory.observations[name][CAMERA]
            depth = np.nan_to_num(xyz[..., 2])
            seen_robot = robot & (depth > 0)
            changed = ~np.isclose(picture.depth, depth, rtol=0.0, atol=0.0005 + 1e-6)  # removed, maybe filled
            assert (seen_robot & ~changed).sum() <= 0.05 * seen_robot.sum()  # flying pixels at the silhouette survive
            assert (changed & ~robot).sum() <= 0.01 * ((depth > 0) & ~robot).sum()
            hidden_rgb = rgb.copy()
            hidden_rgb[robot] = 0
            truth[name] = CameraImage(hidden_rgb, np.where(robot, 0.0, depth).astype(np.float32), picture.K,
                                      picture.T_world_optical)
            visible[name] = {CAMERA: CameraImage(rgb, depth.astype(np.float32), picture.K, picture.T_world_optical)}
            robots[name] = robot
        truth_init, truth_final = fill_robot_pixels(truth["init"], truth["final"], robots["init"], robots["final"])
        expected = np.subtract(*encoder.encode([{CAMERA: truth_init}, {CAMERA: truth_final}]))
        with_robot = np.subtract(*encoder.encode([visible["init"], visible["final"]]))
        ours = z[entry["id"]]
        cosine = ours @ expected / np.linalg.norm(ours) / np.linalg.norm(expected)
        assert cosine > 0.95, cosine
        assert np.linalg.norm(ours - expected) < np.linalg.norm(with_robot - expected)


def test_robot_pixels_are_filled_from_the_other_observation_where_it_saw_the_scene():
    K, T = np.eye(3), np.eye(4)
    depth_init, depth_final = np.full((4, 5), 1.0, np.float32), np.full((4, 5), 2.0, np.float32)
    depth_final[3, 4] = 0.0  # no return in O_final
    rgb_init, rgb_final = np.full((4, 5, 3), 10, np.uint8), np.full((4, 5, 3), 20, np.uint8)
    arm_init, arm_final = np.zeros((4, 5), bool), np.zeros((4, 5), bool)
    arm_init[0, :2] = True  # the arm at START
    arm_final[1:, 3:] = True  # at END, elsewhere
    arm_final[0, 0] = True  # and one pixel where it stood at START too
    for mask, depth, rgb in ((arm_init, depth_init, rgb_init), (arm_final, depth_final, rgb_final)):
        depth[mask], rgb[mask] = 0.0, 0
    init, final = fill_robot_pixels(CameraImage(rgb_init, depth_init, K, T), CameraImage(rgb_final, depth_final, K, T),
                                    arm_init, arm_final)
    assert init.depth[0, 1] == 2.0 and (init.rgb[0, 1] == 20).all()  # O_final saw the scene there
    assert init.depth[0, 0] == 0.0 and (init.rgb[0, 0] == 0).all()  # the arm in both: stays empty
    assert final.depth[1, 3] == 1.0 and (final.rgb[2, 4] == 10).all()
    assert final.depth[3, 4] == 1.0  # removed by the filter, so filled (the other saw it)
    untouched = ~(arm_init | arm_final)
    assert (init.depth[untouched] == 1.0).all() and (final.depth[untouched & (depth_final > 0)] == 2.0).all()
    assert depth_init[0, 1] == 0.0  # the inputs are not modified


def test_dataset_json_records_the_capture_configuration_and_the_encoder(converted):
    info = json.loads((converted.dataset / "dataset.json").read_text())
    assert info["perception"] == capture_part(load_perception_config("azure_kinect"))
    assert info["robot"] == "kinova_j2s6s200" and info["cloud_topics"] == {"/points2": CAMERA}
    assert info["encoder"]["digest"] == encoder_digest(converted.recording.encoder)
    assert converted.summary["mode_labels"] == {"pull": 2, "push": 2}
    assert converted.summary["bags_with_problems"] == 0


def test_bags_missing_a_topic_or_a_keypose_are_reported_and_the_rest_converts(teleop_recording, tmp_path, capsys):
    no_joints = tmp_path / "no_joint_states"
    rewrite(teleop_recording.bag, no_joints, lambda topic, index: topic != "/joint_states")
    no_reach = tmp_path / "no_reach"  # episode 1's REACH (the 6th keypose) was never marked
    rewrite(teleop_recording.bag, no_reach, lambda topic, index: not (topic == "/keypose" and index == 5))
    missing = tmp_path / "does_not_exist"
    out = tmp_path / "ds"
    code = cli.main(["bag2dataset", str(no_joints), str(no_reach), str(missing), "--out", str(out),
                     "--encoder", str(teleop_recording.encoder)])
    printed = capsys.readouterr().out
    assert code == 0
    assert "missing required topic(s) ['/joint_states']" in printed
    assert "episode 1: no keypose marked for REACH; skipped" in printed
    assert f"no bag at {missing}" in printed
    report = json.loads((out / "bag2dataset.json").read_text())
    assert report["trajectories"] == 3 and [len(b["converted"]) for b in report["bags"]] == [0, 3, 0]
    assert [e["episode"] for e in DatasetReader(out).entries] == [0, 2, 3]
    # nothing to convert at all: reported, exit code 1
    assert cli.main(["bag2dataset", str(no_joints), "--out", str(tmp_path / "empty"), "--encoder", str(teleop_recording.encoder)]) == 1
    assert "missing required topic(s)" in capsys.readouterr().out
