"""Which clouds make each observation of an episode: chosen by header stamp, from START on; which
keyposes and clouds recorded around START belong to the episode."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.bags.recorder import Recorder
from actaim2.bags.writer import BagWriter
from actaim2.finetune.bag_episodes import _Episode, choose_clouds, read_episodes
from actaim2.keypose import Keypose
from sim_bags import TOPICS, T, _header, _serialize, _spec, cloud_msg, keypose_msg

CAMERAS = {"/points2": "azure_kinect"}
S = 10**9  # ns per s


def episode(start: float, marks: list[float], clouds: list[float]) -> _Episode:
    ep = _Episode(0, "obj", int(start * S))
    for phase, t in enumerate(marks):
        ep.marked[phase] = (phase, Keypose(phase, np.zeros(3), np.array([0, 0, 0, 1.0]), phase >= 2), int(t * S))
    ep.clouds = [("/points2", i, int(t * S)) for i, t in enumerate(clouds)]
    return ep


def chosen_index(chosen: dict, name: str) -> int:
    return chosen[name]["azure_kinect"][1]


def test_each_observation_is_the_latest_cloud_stamped_before_its_keypose():
    # a cloud from before the reset (index 0) is never used; clouds 1..8 at 1 Hz from START
    ep = episode(10.0, marks=[11.5, 13.2, 15.0, 16.9], clouds=[9.5, 10.2, 11.2, 12.2, 13.2, 14.2, 15.2, 16.2, 17.2])
    chosen = choose_clouds(ep, int(19.0 * S), CAMERAS)
    assert {name: chosen_index(chosen, name) for name in chosen} == {"init": 1, "o0": 2, "o1": 4, "o2": 5, "o3": 7, "final": 8}


def test_init_marked_at_start_takes_the_first_cloud_when_it_precedes_reach():
    ep = episode(46.617, marks=[46.617, 50.5, 53.0, 55.0], clouds=[46.658, 47.658, 48.658, 50.658, 54.0])
    chosen = choose_clouds(ep, int(60 * S), CAMERAS)
    assert chosen_index(chosen, "o0") == chosen_index(chosen, "init") == 0 and chosen_index(chosen, "o1") == 2
    late = episode(46.617, marks=[46.617, 46.62, 53.0, 55.0], clouds=[46.658, 54.0])  # REACH marked before any cloud
    with pytest.raises(ValueError, match="no /points2 cloud stamped between START and o0"):
        choose_clouds(late, int(60 * S), CAMERAS)


def test_clouds_on_another_clock_are_named_as_the_likely_cause():
    ep = episode(1.7e9, marks=[1.7e9 + 1, 1.7e9 + 2, 1.7e9 + 3, 1.7e9 + 4], clouds=[12.0, 13.0])  # wall vs sim time
    with pytest.raises(ValueError, match="on one clock"):
        choose_clouds(ep, int((1.7e9 + 5) * S), CAMERAS)


def test_a_keypose_received_just_before_start_belongs_to_the_episode_and_the_reset_scene_does_not(tmp_path):
    """Episode bags as bag_recorder writes them (its pipeline, 0.5 s start grace): episode 1's INIT
    keypose, stamped with START, reaches the recorder 20 ms before START (runs/teleop's episode 48),
    after a cloud of the scene before the reset; episode 0's arrives 21 ms after START."""
    recorder = Recorder(lambda name: BagWriter(tmp_path / name), start_grace_ns=S // 2, start_grace_bytes=2**20)
    for topic, (_, reliable, latched) in TOPICS.items():
        recorder.add_topic(_spec(topic), reliable, latched and topic != "/episode")
    xyz = np.dstack([*np.meshgrid(np.linspace(-0.1, 0.1, 4), np.linspace(-0.1, 0.1, 3)), np.ones((3, 4))]).astype(np.float32)

    def put(topic: str, received_ns: int, msg) -> None:
        recorder.put(topic, received_ns, _serialize(topic, msg))

    def keypose(phase: int, stamp_ns: int):
        return keypose_msg(stamp_ns, Keypose(phase, np.zeros(3), np.array([0, 0, 0, 1.0]), phase >= 2))

    put("/tf_static", 0, T["tf2_msgs/msg/TFMessage"]([]))
    for episode, start, init_after_start in ((0, 10.0, 0.021), (1, 15.0, -0.02)):
        s0 = int(start * S)
        event = T["actaim2_msgs/msg/EpisodeEvent"]
        received = [(-0.39, "/points2", cloud_msg(s0 - int(0.4 * S), xyz, None)),  # the scene before the reset
                    (init_after_start, "/keypose", keypose(0, s0)),
                    (0.0, "/episode", event(_header(s0), episode, 0, "drawer", False, "")),
                    (4.0, "/episode", event(_header(s0 + 4 * S), episode, 1, "drawer", True, ""))]
        received += [(phase, "/keypose", keypose(phase, s0 + phase * S)) for phase in (1, 2, 3)]
        for t in (0.04, 2.5, 3.5):
            received.append((t, "/joint_states", T["sensor_msgs/msg/JointState"](_header(s0 + int(t * S)), ["j1"], np.zeros(1),
                                                                               np.zeros(1), np.zeros(0))))
            received.append((t + 0.01, "/points2", cloud_msg(s0 + int(t * S), xyz, None)))
        for t, topic, msg in sorted(received, key=lambda r: r[0]):  # as bag_recorder's _on_message hands them on
            if topic == "/episode" and msg.event == 0:
                recorder.start_bag(f"episode_{episode:04d}", s0)
            put(topic, s0 + int(t * S), msg)
            if topic == "/episode" and msg.event == 1:
                recorder.end_bag()
    counts = recorder.stop().topics
    assert counts["/keypose"].recorded == counts["/points2"].recorded == 8  # the reset scene's clouds are in the bags

    problems = []
    for episode, start in ((0, 10.0), (1, 15.0)):
        (demo,) = read_episodes(tmp_path / f"episode_{episode:04d}", CAMERAS, problems.append)
        assert [k.phase for k in demo.keyposes] == [0, 1, 2, 3]
        assert demo.observations["init"]["azure_kinect"].stamp_ns == int((start + 0.04) * S)  # not the reset scene's
    assert problems == []
