"""bag_player: publishes a rosbag2 bag's messages with their original timing, like ``ros2 bag play``.

A thin adapter over ``actaim2.bags``: :class:`~actaim2.bags.source.BagSource` opens the bag (MCAP
or sqlite3, split or not) and checks every message, :class:`~actaim2.bags.playback.Player` times
them (rate factor, start offset, loop, optional /clock); this node creates one publisher per
played topic with the QoS the topic was recorded with (a transient-local /tf_static is latched
again, holding all its recorded messages) and publishes the CDR bytes as they are.

Never fatal: a topic whose type has no Python class here or whose definition rosbags cannot
parse, a message that does not deserialize, a truncated or unreadable file are each reported
(with topic and message index) and skipped while the rest plays. The node ends by itself when
the bag is played (unless ``loop``), logging what it published and its timing error. Before it
ends it waits (``wait_for_all_acked``, as ``ros2 bag play --wait-for-all-acked``) until every
reliable subscriber has acknowledged every message: a process that exits with messages still in
its DDS history drops them, and a subscriber would miss the end of the bag.
"""
from __future__ import annotations

import json
import threading
import time
from pathlib import Path

from rclpy.duration import Duration
from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from actaim2.bags.playback import Player, PlayOptions, parse_remaps
from actaim2.bags.qos import replay_choice
from actaim2.bags.source import BagSource
from actaim2_policy.ros_bags import message_class, rclpy_qos
from actaim2_ros.main import spin_until
from actaim2_ros.params import declare_parameters
from actaim2_ros.stamps import stamp_msg

PARAMETERS = {
    # name: (default, description)
    "bag": ("", "bag directory (with metadata.yaml) or a single .mcap / .db3 file"),
    # rclpy cannot declare an empty string list: [""] stands for "none given".
    "topics": ([""], "topics to play; [\"\"] = every topic of the bag"),
    "remap": ([""], "topic remappings applied when publishing, each '/recorded:=/published'; [\"\"] = none"),
    "rate": (1.0, "playback speed factor (2.0 = twice as fast)"),
    "start_offset": (0.0, "s into the bag where playback starts"),
    "loop": (False, "play again from the start offset when the bag ends, until stopped"),
    "clock_rate": (0.0, "Hz: publish the bag time on /clock at this rate (for use_sim_time nodes); 0 = no /clock"),
    "start_delay": (0.5, "s between creating the publishers and the first message (lets subscribers match)"),
    "wait_for_subscribers": ([""], "published topics that must each have a subscriber before playback starts; [\"\"] = none"),
    "wait_for_all_acked": (5.0, "s to wait at the end until reliable subscribers have acknowledged every message; 0 = exit at once"),
    "summary_file": ("", "write the final summary as JSON to this file (scripts, benchmarks); empty = none"),
}


class BagPlayer(Node):
    def __init__(self, stop: threading.Event) -> None:
        super().__init__("bag_player")
        p = declare_parameters(self, PARAMETERS)
        if not p["bag"]:
            raise ValueError("parameter 'bag' is empty: give a bag directory or an .mcap/.db3 file")
        self._stop = stop  # set on Ctrl-C / SIGTERM, or by _play when the bag is played
        self._summary_file = str(p["summary_file"])
        self._ack_timeout = float(p["wait_for_all_acked"])
        remap = parse_remaps([r for r in p["remap"] if r])
        options = PlayOptions(
            rate=float(p["rate"]),
            start_offset_ns=int(float(p["start_offset"]) * 1e9),
            loop=bool(p["loop"]),
            clock_period_ns=int(1e9 / float(p["clock_rate"])) if float(p["clock_rate"]) > 0 else 0,
        )
        source = BagSource(p["bag"], self._report)
        selected = {t for t in p["topics"] if t}
        for topic in sorted(selected - set(source.topics)):
            self._report(f"topic {topic}: not in the bag")
        publishers, by_output = {}, {}
        for topic in source.playable():
            if selected and topic.name not in selected:
                continue
            try:
                msg_class = message_class(topic.msgtype)
            except ImportError as exc:
                self._report(f"topic {topic.name}: unknown message type {topic.msgtype} ({exc}); its {topic.count} message(s) are skipped")
                continue
            choice = replay_choice(topic.offered_qos, topic.count)
            publisher = self.create_publisher(msg_class, remap.get(topic.name, topic.name), rclpy_qos(choice))
            publishers[topic.name] = publisher.publish
            by_output[publisher.topic_name] = publisher
        clock = None
        if options.clock_period_ns:
            clock_pub = self.create_publisher(Clock, "/clock", 10)
            clock = lambda ns: clock_pub.publish(Clock(clock=stamp_msg(ns)))  # noqa: E731
            by_output[clock_pub.topic_name] = clock_pub
        awaited = [t for t in p["wait_for_subscribers"] if t]
        if missing := [t for t in awaited if t not in by_output]:
            raise ValueError(f"wait_for_subscribers names topics this bag does not play: {missing} (played: {sorted(by_output)})")
        self._awaited = [by_output[t] for t in awaited]
        self._publishers = list(by_output.values())
        self._player = Player(source, options, publishers, clock, stop)
        self._thread = threading.Thread(target=self._play, args=(float(p["start_delay"]),), name="bag_player", daemon=True)
        self._thread.start()
        self.get_logger().info(
            f"playing {p['bag']}: {sorted(remap.get(t, t) for t in publishers)} at rate {options.rate:g}"
            f"{', looping' if options.loop else ''}{', /clock' if clock else ''}"
        )

    def _report(self, text: str) -> None:
        self.get_logger().warning(text)

    def _play(self, delay: float) -> None:
        if self._awaited:
            self.get_logger().info(f"waiting for subscribers on {[p.topic_name for p in self._awaited]}")
        while not self._stop.is_set() and not all(p.get_subscription_count() for p in self._awaited):
            self._stop.wait(0.05)
        if not self._stop.wait(delay):
            self._player.run()
        self._stop.set()

    def finish(self) -> int:
        self._thread.join()
        if self._ack_timeout > 0:
            deadline = time.monotonic() + self._ack_timeout  # one budget for all publishers together
            unacked = [
                p.topic_name for p in self._publishers
                if not p.wait_for_all_acked(Duration(seconds=max(0.0, deadline - time.monotonic())))
            ]
            if unacked:
                self.get_logger().warning(f"not every subscriber acknowledged every message within {self._ack_timeout:g} s on {unacked}")
        stats = self._player.stats
        timing = stats.timing_ms()
        self.get_logger().info(
            f"published {sum(stats.published.values())} message(s) in {stats.seconds:.2f} s ({stats.passes} pass(es))"
            + (f"; timing error p50 {timing['p50']:.2f} ms, p99 {timing['p99']:.2f} ms, max {timing['max']:.2f} ms" if timing else "")
        )
        for topic, count in sorted(stats.published.items()):
            self.get_logger().info(f"  {topic}: {count}")
        if self._summary_file:
            Path(self._summary_file).write_text(json.dumps(stats.as_dict(), indent=1))
        return 0


def main(args: list[str] | None = None) -> int:
    return spin_until(BagPlayer, "bag_player", args)


if __name__ == "__main__":
    raise SystemExit(main())
