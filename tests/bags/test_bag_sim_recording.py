"""bag_recorder on the running simulator (azure_kinect rig): the command that records the golden
bags (bags/README.md) works, and the bag holds what fusion_node needs to replay it."""
from __future__ import annotations

import time

import yaml
from rosbags.highlevel import AnyReader

from bagtools import TYPESTORE
from harness import wait_for

SIM = dict(rig="azure_kinect", render_path="raycast", camera_rate=2.0, category="storage_furniture", instance=0, seed=0)


def test_recording_the_simulator(start_node, tmp_path):
    sim = start_node("actaim2_sim", "sim_node", SIM)
    recorder = start_node("actaim2_policy", "bag_recorder", {"output": str(tmp_path / "sim_bag"), "discovery_period": 0.2})
    assert wait_for(lambda: all(f"{t} [" in recorder.output() for t in ("/points2", "/tf_static", "/joint_states")), 90.0), (
        sim.output()[-3000:] + recorder.output()
    )
    time.sleep(3.0)  # >= 2 clouds at 2 Hz sim time
    assert recorder.stop() == 0, recorder.output()

    messages = {}
    with AnyReader([tmp_path / "sim_bag"], default_typestore=TYPESTORE) as reader:
        for connection, _, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(reader.deserialize(raw, connection.msgtype))
    clouds = messages["/points2"]
    assert len(clouds) >= 2 and (clouds[0].width, clouds[0].height, clouds[0].header.frame_id) == (320, 288, "depth_camera_link")
    edges = {(t.header.frame_id, t.child_frame_id) for m in messages["/tf_static"] for t in m.transforms}
    assert any(child == "depth_camera_link" for _, child in edges), edges
    assert len(messages["/joint_states"]) > 10
    info = yaml.safe_load((tmp_path / "sim_bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    qos = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"][0] for t in info["topics_with_message_count"]}
    assert qos["/points2"]["reliability"] == "best_effort" and qos["/tf_static"]["durability"] == "transient_local"
