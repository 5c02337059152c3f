"""bag_recorder: records topics to a rosbag2 bag (MCAP with lz4/zstd chunks, or sqlite3), like
``ros2 bag record``, on machines that have no ros2 CLI.

A thin adapter over ``actaim2.bags``: it discovers the requested topics on the graph, subscribes
to each with ``raw=True`` (the CDR bytes go to the bag untouched; the message class is only
needed for its type support) and a QoS that matches every publisher (actaim2.bags.qos), and hands
each message with its receive time (node clock: sim time under use_sim_time) to the
:class:`~actaim2.bags.recorder.Recorder`, whose writer thread compresses and writes.

Recorded per topic: the publishers' offered QoS (a player re-latches /tf_static from it), the
type's .msg definition as rosbag2 stores it, and the publisher's type hash. DDS losses of
best-effort topics come from the message-lost event and are reported with the queue drops at
the end. Ctrl-C or SIGTERM: everything queued is written, the bag is closed, the summary
logged. A write error (full disk) stops the recording with its reason, keeps the bag readable,
and exits with code 1. A recorder that dies (SIGKILL, out of memory) keeps what it received up
to ``max_chunk_age`` before (chunks go to disk by age as well as by size); ``actaim2
bag-reindex`` then finishes the bag.

With ``split_by_episode`` every START on the episode topic opens a new bag
``<output>/episode_<n>`` and the matching END closes it; latched topics (/tf_static) are
repeated at the start of each bag so every episode replays on its own. Topics reach the
recorder in no guaranteed order: the INIT keypose control_node publishes right after START was
seen arriving 21 ms after it in one episode and just before it in another (then lost between
bags). So the messages received between END and START are held, the last ``start_grace``
seconds of receive time (node clock) up to ``start_grace_bytes``, and START's bag begins with
those received at most ``start_grace`` before START, each written with its receive time: a bag's
first messages may precede its START by up to ``start_grace``. Readers keep what is stamped
at or after START (``actaim2 bag2dataset``); the rest is counted as outside episodes.
"""
from __future__ import annotations

import json
import re
import threading
import time
from functools import partial
from pathlib import Path

from actaim2_msgs.msg import EpisodeEvent
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.serialization import deserialize_message

from actaim2.bags.definitions import MessageDefinitions, UnknownMessageType
from actaim2.bags.metadata import TopicSpec
from actaim2.bags.qos import record_choice
from actaim2.bags.recorder import Recorder, RecordSummary, unique_path
from actaim2.bags.writer import (
    COMPRESSIONS,
    DEFAULT_CHUNK_SIZE,
    DEFAULT_MAX_CHUNK_AGE,
    STORAGES,
    BagWriter,
)
from actaim2_policy.ros_bags import bag_qos, install_prefixes, message_class, rclpy_qos
from actaim2_ros.main import spin_until
from actaim2_ros.params import declare_parameters

PARAMETERS = {
    # name: (default, description)
    "output": ("", "bag directory (episode mode: the folder of the episode bags); empty = rosbag2_<date>-<time> here"),
    "topics": (
        ["/points2", "/tf_static", "/joint_states", "/keypose", "/interaction_mode", "/episode"],
        "topics to record once a publisher appears (add /ortho_views to keep the views)",
    ),
    "topic_patterns": (["^/cameras/[^/]+/points$"], "regular expressions: matching topics are recorded too (sim camera clouds)"),
    "storage": ("mcap", f"storage format: {' | '.join(STORAGES)}"),
    "compression": ("lz4", f"MCAP chunk compression: {' | '.join(COMPRESSIONS)} (sqlite3: none)"),
    "chunk_size": (DEFAULT_CHUNK_SIZE, "bytes: an MCAP chunk is compressed and written once it holds this much"),
    "max_chunk_age": (
        DEFAULT_MAX_CHUNK_AGE,
        "s: an MCAP chunk (sqlite3: the uncommitted messages) is also written once its oldest "
        "message has waited this long, so a recorder that dies loses at most that much; "
        "0 = by size only",
    ),
    "max_bag_size": (0, "bytes: start a new storage file when the current one reaches this size; 0 = never"),
    "max_bag_duration": (0.0, "s: start a new storage file when the current one spans this long; 0 = never"),
    "split_by_episode": (False, "one bag per episode: START on episode_topic opens it, END closes it"),
    "episode_topic": ("/episode", "actaim2_msgs/EpisodeEvent topic that delimits episodes"),
    "start_grace": (0.5, "s: split_by_episode: messages received at most this long before START go into its bag "
                         "(topics arrive in no fixed order); earlier ones between END and START are not recorded"),
    "start_grace_bytes": (32 * 2**20, "bytes: split_by_episode: messages held between END and START for start_grace at most "
                                      "(beyond, the oldest are given up)"),
    "queue_limit": (256 * 2**20, "bytes: messages waiting for the writer thread at most; beyond, new ones are dropped and counted"),
    "best_effort_depth": (10, "history depth of best-effort subscriptions (reliable ones keep all)"),
    "discovery_period": (0.5, "s between two looks at the graph for requested topics that have no subscription yet"),
    "report_period": (10.0, "s between progress lines in the log; 0 = only the final summary"),
    "summary_file": ("", "write the final summary as JSON to this file (scripts, benchmarks); empty = none"),
}


class BagRecorder(Node):
    def __init__(self, stop: threading.Event) -> None:
        super().__init__("bag_recorder")
        p = declare_parameters(self, PARAMETERS)
        self._stop = stop  # set on Ctrl-C / SIGTERM (then finish() writes what is queued), or here on a write error
        self._storage, self._compression = str(p["storage"]), str(p["compression"])
        if self._storage not in STORAGES or self._compression not in COMPRESSIONS:
            raise ValueError(f"storage must be one of {list(STORAGES)} and compression one of {list(COMPRESSIONS)}")
        if self._storage == "sqlite3" and self._compression != "none":
            self.get_logger().warning(f"compression '{self._compression}' applies to MCAP chunks only: sqlite3 is written uncompressed")
            self._compression = "none"
        self._chunk_size, self._max_size = int(p["chunk_size"]), int(p["max_bag_size"])
        self._max_chunk_age = float(p["max_chunk_age"])
        self._max_duration_ns = int(float(p["max_bag_duration"]) * 1e9)
        self._episodes = bool(p["split_by_episode"])
        self._episode_topic = str(p["episode_topic"])
        self._best_effort_depth = int(p["best_effort_depth"])
        self._summary_file = str(p["summary_file"])
        self._wanted = set(p["topics"]) | ({self._episode_topic} if self._episodes else set())
        try:
            self._patterns = [re.compile(x) for x in p["topic_patterns"] if x]
        except re.error as exc:
            raise ValueError(f"topic_patterns: {exc}") from None
        self._output = Path(p["output"] or time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S")).resolve()
        if not self._episodes and self._output.exists():
            raise ValueError(f"output {self._output} exists already (a bag is never overwritten)")
        self._definitions = MessageDefinitions(install_prefixes())
        self._subscribed: dict[str, object] = {}
        self._refused: set[str] = set()  # topics reported as unrecordable (reported once)
        self._recorder = Recorder(self._make_writer, int(p["queue_limit"]), on_error=self._on_write_error,
                                  start_grace_ns=int(float(p["start_grace"]) * 1e9),
                                  start_grace_bytes=int(p["start_grace_bytes"]))
        if not self._episodes:
            self._recorder.start_bag(self._output.name, self.get_clock().now().nanoseconds)
        self.create_timer(float(p["discovery_period"]), self._discover)
        if float(p["report_period"]) > 0:
            self.create_timer(float(p["report_period"]), self._progress)
        self._discover()
        self.get_logger().info(
            f"recording {sorted(self._wanted)} + topics matching {[x.pattern for x in self._patterns]} to "
            f"{self._output}{'/episode_<n>' if self._episodes else ''} ({self._storage}, {self._compression})"
        )

    # --- bags -------------------------------------------------------------------------------
    def _make_writer(self, name: str) -> BagWriter:
        path = unique_path(self._output / name) if self._episodes else self._output
        return BagWriter(path, self._storage, self._compression, self._chunk_size, self._max_size,
                         self._max_duration_ns, max_chunk_age=self._max_chunk_age)

    def _on_write_error(self, reason: str) -> None:
        self.get_logger().error(f"recording stopped: {reason}; what reached the disk stays readable")
        self._stop.set()

    # --- topics -------------------------------------------------------------------------------
    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._subscribed or topic in self._refused:
                continue
            if topic not in self._wanted and not any(x.search(topic) for x in self._patterns):
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if publishers:
                self._subscribe(topic, types, publishers)

    def _refuse(self, topic: str, why: str) -> None:
        self._refused.add(topic)
        self.get_logger().warning(f"{topic}: not recorded: {why}")

    def _subscribe(self, topic: str, types: list[str], publishers) -> None:
        if len(types) != 1:
            return self._refuse(topic, f"published with several types {types}")
        msgtype = types[0]
        try:
            msg_class = message_class(msgtype)
            definition = self._definitions.definition(msgtype)
            local_hash = self._definitions.type_hash(msgtype)
        except (ImportError, UnknownMessageType) as exc:
            return self._refuse(topic, str(exc))
        type_hash = str(publishers[0].topic_type_hash)
        if not type_hash.startswith("RIHS01_"):  # a publisher that does not announce its type hash
            type_hash = local_hash
        if type_hash != local_hash:
            self.get_logger().warning(
                f"{topic}: the publisher's {msgtype} ({type_hash}) differs from the installed one ({local_hash}); "
                "the bag stores the installed definition"
            )
        offers = [bag_qos(e.qos_profile) for e in publishers]
        choice = record_choice(offers, self._best_effort_depth)
        spec = TopicSpec(topic, msgtype, definition, type_hash, offers)
        latched = choice.transient_local and topic != self._episode_topic
        self._recorder.add_topic(spec, choice.reliable, latched)
        events = SubscriptionEventCallbacks(message_lost=partial(self._on_lost, topic))
        self._subscribed[topic] = self.create_subscription(
            msg_class, topic, partial(self._on_message, topic), rclpy_qos(choice), event_callbacks=events, raw=True
        )
        self.get_logger().info(
            f"{topic} [{msgtype}]: {'reliable, keep all' if choice.reliable else f'best effort, depth {choice.depth}'}"
            f"{', transient local' if choice.transient_local else ''} ({len(publishers)} publisher(s))"
        )

    def _on_lost(self, topic: str, status) -> None:
        self._recorder.add_lost(topic, int(status.total_count_change))

    def _on_message(self, topic: str, data: bytes) -> None:
        stamp = self.get_clock().now().nanoseconds
        if self._episodes and topic == self._episode_topic:
            event = deserialize_message(data, EpisodeEvent)
            if event.event == EpisodeEvent.START:
                self._recorder.start_bag(f"episode_{event.episode:04d}", stamp)
                self._recorder.put(topic, stamp, data)
            else:
                self._recorder.put(topic, stamp, data)
                self._recorder.end_bag()
            return
        self._recorder.put(topic, stamp, data)

    # --- reporting ----------------------------------------------------------------------------
    def _progress(self) -> None:
        counts = self._recorder.counts()
        self.get_logger().info(
            f"recording {len(self._subscribed)} topic(s): {sum(c.received for c in counts.values())} messages received, "
            f"{sum(c.bytes for c in counts.values()) / 1e6:.1f} MB written, {self._recorder.queued_bytes / 1e6:.1f} MB queued, "
            f"{sum(c.dropped for c in counts.values())} dropped, {sum(c.lost for c in counts.values())} lost in DDS"
        )

    def finish(self) -> int:
        """Write what is queued, close the bag, log (and optionally save) the summary."""
        summary: RecordSummary = self._recorder.stop()
        for line in summary.lines():
            self.get_logger().info(line)
        for bag in summary.bags:
            self.get_logger().info(f"bag: {bag}")
        if self._summary_file:
            Path(self._summary_file).write_text(json.dumps(summary.as_dict(), indent=1))
        return 1 if summary.error else 0


def main(args: list[str] | None = None) -> int:
    return spin_until(BagRecorder, "bag_recorder", args)


if __name__ == "__main__":
    raise SystemExit(main())
