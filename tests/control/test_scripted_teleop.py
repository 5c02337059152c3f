"""scripted_teleop drives the Kinova through sim_node and control_node and produces what a person at
teleop_node produces, recorded by bag_recorder: START, the mode label, the four marked keyposes
(published by control_node), END with the verdict; and the drawer really moved. The scene as in the
paper's fine-tuning data: the middle drawer half-open, the others shut (ResetScene.dof_fractions)."""
from __future__ import annotations

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from harness import wait_for

ROBOT = "kinova_j2s6s200"
SCENE = {"category": "three_drawer_shelf", "instance": 0, "seed": 3, "dof_fraction": 0.5}


def test_scripted_teleop_records_a_pull(start_node, tmp_path):
    start_node("actaim2_sim", "sim_node", {"robot": ROBOT, "camera_rate": 0.0, **SCENE})
    start_node("actaim2_control", "control_node", {"robot": ROBOT})
    recorder = start_node("actaim2_policy", "bag_recorder", {"output": str(tmp_path / "demo"), "discovery_period": 0.2,
                                                             "topics": ["/keypose", "/interaction_mode", "/episode"]})
    # The recorder subscribes to a topic once it sees its publisher (control_node's /keypose):
    # the operator starts only then, or INIT could be published before anyone records it.
    assert wait_for(lambda: "/keypose [" in recorder.output(), 60.0), recorder.output()
    teleop = start_node("actaim2_control", "scripted_teleop", {"robot": ROBOT, "episodes": 1, "modes": ["pull"],
                                                                "joints": ["drawer_1_joint"], "others_fraction": 0.0,
                                                                **SCENE})
    assert wait_for(lambda: not teleop.alive(), 240.0), teleop.output()
    log = teleop.output()
    assert teleop.proc.returncode == 0 and "1/1 episodes succeeded" in log, log
    assert wait_for(lambda: "/episode [" in recorder.output(), 10.0), recorder.output()
    assert recorder.stop() == 0, recorder.output()

    messages: dict[str, list] = {}
    with AnyReader([tmp_path / "demo"], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for connection, _, raw in reader.messages():
            messages.setdefault(connection.topic, []).append(reader.deserialize(raw, connection.msgtype))
    start, end = messages["/episode"]
    assert (start.event, start.object_id, end.event, end.success) == (0, "three_drawer_shelf_000", 1, True), (start, end)
    assert "pull drawer_1_joint" in start.note and "grasp" in start.note
    assert "moved +0.3" in end.note or "moved +0.4" in end.note, end.note  # > 30 % of the range the asked way
    assert [m.label for m in messages["/interaction_mode"]] == ["pull"]
    keyposes = messages["/keypose"]
    assert [k.phase for k in keyposes] == [0, 1, 2, 3] and [k.gripper_closed for k in keyposes] == [False, False, True, True]
    assert all(k.header.frame_id == "world" for k in keyposes)
    stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in (start, *keyposes, end)]
    assert stamps == sorted(stamps)  # START, the keyposes in the order marked, END (sim time)
