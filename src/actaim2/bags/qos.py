"""QoS decisions of the recorder and the player, on ``rosbags`` Qos values (the ROS nodes convert).

Recording (as rosbag2 adapts its requests to the publishers' offers): a topic is subscribed
reliable only if every publisher offers reliable, transient-local only if every publisher is
transient-local; otherwise the subscription could not match them all. Reliable topics are
subscribed KEEP_ALL (a slow moment never overwrites an unread message), best-effort ones
KEEP_LAST with a depth.

Replay: a topic is published as it was offered when recorded. A transient-local (latched)
topic keeps every recorded message of the topic (up to ``LATCHED_DEPTH_MAX``) for late joiners:
/tf_static is usually sent by several publishers, and each message holds only its own edges.
"""
from __future__ import annotations

from dataclasses import dataclass

from rosbags.interfaces import Qos, QosDurability, QosReliability

LATCHED_DEPTH_MAX = 100  # like tf2's /tf_static listener; bounds the memory of a latched high-rate topic
# Volatile topics: the publisher's history while playing. A reliable KEEP_LAST writer drops its
# oldest unacknowledged sample when the history is full, so a reliable topic gets 100 (1 s of
# 100 Hz joint states: a subscriber stalled by a busy machine still gets every message);
# best-effort topics (clouds) keep few, as a sensor driver does.
REPLAY_DEPTH_RELIABLE, REPLAY_DEPTH_BEST_EFFORT = 100, 10


@dataclass(frozen=True)
class QosChoice:
    reliable: bool
    transient_local: bool
    depth: int  # 0 = KEEP_ALL


def record_choice(offers: list[Qos], best_effort_depth: int) -> QosChoice:
    """The subscription that matches every offer (at least one offer is expected)."""
    reliable = bool(offers) and all(q.reliability == QosReliability.RELIABLE for q in offers)
    latched = bool(offers) and all(q.durability == QosDurability.TRANSIENT_LOCAL for q in offers)
    return QosChoice(reliable, latched, 0 if reliable else best_effort_depth)


def replay_choice(offered: list[Qos], message_count: int) -> QosChoice:
    """The publisher for a recorded topic. Without recorded QoS: reliable, volatile (ROS default)."""
    reliable = not offered or all(q.reliability != QosReliability.BEST_EFFORT for q in offered)
    latched = bool(offered) and all(q.durability == QosDurability.TRANSIENT_LOCAL for q in offered)
    if latched:
        depth = min(max(message_count, 1), LATCHED_DEPTH_MAX)
    else:
        depth = REPLAY_DEPTH_RELIABLE if reliable else REPLAY_DEPTH_BEST_EFFORT
    return QosChoice(reliable, latched, depth)
