"""The two searches of the grounding experiment on synthetic rewards, and its reward definition."""
from __future__ import annotations

import numpy as np

from actaim2.eval.grounding import CrossEntropySearch, ThompsonBandit, reward


def test_thompson_bandit_finds_the_rewarding_cluster() -> None:
    rng = np.random.default_rng(0)
    p = np.array([0.1, 0.1, 0.8, 0.1, 0.05, 0.1, 0.1, 0.1])
    bandit = ThompsonBandit(len(p), rng)
    pulls = []
    for _ in range(150):
        arm = bandit.choose()
        bandit.update(arm, int(rng.random() < p[arm]))
        pulls.append(arm)
    assert np.mean(np.array(pulls[-50:]) == 2) > 0.7


def test_cem_moves_to_the_rewarding_region() -> None:
    rng = np.random.default_rng(0)
    target = np.array([2.0, -1.5])
    search = CrossEntropySearch(np.zeros(2), np.full(2, 1.5), rng)
    rewards = []
    for _ in range(150):
        v = search.propose()
        r = int(np.linalg.norm(v - target) < 1.0)
        search.update(v, r)
        rewards.append(r)
    assert np.linalg.norm(search.mean - target) < 1.0
    assert np.mean(rewards[-30:]) > np.mean(rewards[:30]) + 0.3


def test_reward_is_distance_to_the_goal_end() -> None:
    record = {"initial": {"drawer": 0.5, "door": 0.5}, "fractions": {"drawer": 0.35, "door": -0.1}}
    assert reward(record, "drawer", +1) == 1  # ends at 0.85 of the range: within 0.2 of the open end
    assert reward(record, "drawer", -1) == 0
    assert reward(record, "door", -1) == 0  # 0.4: not within 0.2 of closed
