"""Which clouds make each observation of an episode: chosen by header stamp, from START on."""
from __future__ import annotations

import numpy as np
import pytest

from actaim2.finetune.bag_episodes import _Episode, choose_clouds
from actaim2.keypose import Keypose

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
