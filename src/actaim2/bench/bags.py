"""`actaim2 bench bags`: bag_recorder throughput, CPU and loss under a ring5 replay; bag_player timing.

The load is a ring5 rig's: five ring5 clouds (320x240, xyz + rgb, point_step 32, 2.46 MB
each) at 10 Hz plus /joint_states at 100 Hz and a latched /tf_static, ~123 MB/s. It is made as a
real replay: a one-second source bag of ray-cast ring5 frames (``actaim2.bench.perception``'s
scene, each frame with its own per-point depth noise so compression sees sensor-like data) is
played in a loop by ``bag_player`` in one process and recorded by ``bag_recorder`` in another
(``ros2 run``, a private ROS_DOMAIN_ID, loopback only), with the recorder's default MCAP lz4.

Reported per playback rate factor (1.0 = the target rates): what the player published and the
recorder recorded per topic (loss); the recorder's MB/s and messages/s over the span from the
first to the last recorded message; its CPU use during the replay (/proc, user + system, all
threads; 100% = one core); the bag's size on disk; the player's timing error (publish time
minus due time) p50/p99. When the targets (zero loss
on reliable topics, <= 1% on best-effort clouds) fail at a rate, the next lower rate is tried,
so the table ends at the rate the recorder holds.

Other jobs on the machine take CPU from both processes: the load average is printed before and
after; quote it with the figures.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from actaim2.bench.processes import private_ros_env, ros_run_command, start_logged, stop_group
from actaim2.profiling import cpu_seconds

CLOUD_RATE, JOINT_RATE = 10.0, 100.0  # Hz at rate factor 1
T0 = 1_700_000_000 * 10**9


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--duration", type=float, default=10.0, help="s of replay per rate factor")
    parser.add_argument("--rates", type=float, nargs="+", default=[1.0, 0.5, 0.25],
                        help="rate factors tried in turn until the loss targets hold")
    parser.add_argument("--compression", default="lz4", choices=["lz4", "zstd", "none"])
    parser.add_argument("--storage", default="mcap", choices=["mcap", "sqlite3"])
    parser.add_argument("--frames", type=int, default=10, help="distinct ring5 frames in the source bag (looped)")
    parser.add_argument("--workdir", type=Path, help="keep the bags here (default: a temporary folder, removed)")


def make_source_bag(path: Path, frames: int) -> dict[str, int]:
    """One second of ring5 clouds at 10 Hz + joint states at 100 Hz + /tf_static, uncompressed."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )
    from rosbags.typesys import Stores, get_typestore

    from actaim2.bags.definitions import MessageDefinitions
    from actaim2.bags.metadata import TopicSpec
    from actaim2.bags.writer import BagWriter
    from actaim2.bench.perception import build_scene
    from actaim2.geometry import matrix_to_pose
    from actaim2.perception.cloud_codec import encode

    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    definitions = MessageDefinitions(os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep))

    def topic(name: str, msgtype: str, reliable: bool, latched: bool = False) -> TopicSpec:
        """Offered as a ROS publisher offers it (what bag_recorder records): the player replays that QoS."""
        infinite = QosTime(9223372036, 854775807)
        offer = Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
                    QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE, infinite, infinite,
                    QosLiveliness.AUTOMATIC, infinite, False)
        return TopicSpec(name, msgtype, definitions.definition(msgtype), definitions.type_hash(msgtype), [offer])

    def header(t_ns: int, frame: str):
        return T["std_msgs/msg/Header"](T["builtin_interfaces/msg/Time"](t_ns // 10**9, t_ns % 10**9), frame)

    scene = build_scene("ring5")
    rng = np.random.default_rng(0)
    writer = BagWriter(path, "mcap", "none")
    cams = [(writer.add_topic(topic(c.topic, "sensor_msgs/msg/PointCloud2", reliable=False)), c) for c in scene.cameras]
    js = writer.add_topic(topic("/joint_states", "sensor_msgs/msg/JointState", reliable=True))
    tf = writer.add_topic(topic("/tf_static", "tf2_msgs/msg/TFMessage", reliable=True, latched=True))
    transforms = []
    for cam in scene.cameras:
        for parent, child, matrix in cam.tf_chain:
            position, quat = matrix_to_pose(matrix)
            transforms.append(T["geometry_msgs/msg/TransformStamped"](header(T0, parent), child, T["geometry_msgs/msg/Transform"](
                T["geometry_msgs/msg/Vector3"](*map(float, position)), T["geometry_msgs/msg/Quaternion"](*map(float, quat)))))
    writer.write(tf, T0, bytes(store.serialize_cdr(T["tf2_msgs/msg/TFMessage"](transforms), "tf2_msgs/msg/TFMessage")))
    counts = {"/tf_static": 1, "/joint_states": 0, **{c.topic: 0 for c in scene.cameras}}
    names, positions = list(scene.joints), np.array(list(scene.joints.values()))
    cloud_period, joint_period = int(1e9 / CLOUD_RATE), int(1e9 / JOINT_RATE)
    for tick in range(int(frames * JOINT_RATE / CLOUD_RATE)):
        t = T0 + tick * joint_period
        joints = T["sensor_msgs/msg/JointState"](header(t, ""), names, positions + 0.001 * tick, np.zeros(0), np.zeros(0))
        writer.write(js, t, bytes(store.serialize_cdr(joints, "sensor_msgs/msg/JointState")))
        counts["/joint_states"] += 1
        if (t - T0) % cloud_period == 0:
            for topic_id, cam in cams:
                noisy = cam.xyz * (1.0 + rng.normal(0.0, 0.002, cam.xyz.shape[:2]))[..., None]  # ToF-like, along the ray
                wire = encode(noisy.astype(np.float32), cam.rgb)
                fields = [T["sensor_msgs/msg/PointField"](f.name, f.offset, f.datatype, f.count) for f in wire.fields]
                msg = T["sensor_msgs/msg/PointCloud2"](header(t, cam.frame_id), wire.height, wire.width, fields, False,
                                                       wire.point_step, wire.row_step, np.frombuffer(wire.data, np.uint8), False)
                writer.write(topic_id, t, bytes(store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")))
                counts[cam.topic] += 1
    writer.close()
    return counts


def writer_only(source: Path, storage: str, compression: str, workdir: Path, repeats: int = 3) -> tuple[float, float]:
    """MB/s and CPU % of the recording pipeline alone (queue + writer thread + disk), no DDS:
    the headroom of our code, apart from receiving and from the other processes."""
    from actaim2.bags.metadata import TopicSpec
    from actaim2.bags.recorder import Recorder
    from actaim2.bags.source import BagSource
    from actaim2.bags.writer import BagWriter

    bag = BagSource(source, print)
    messages = list(bag.messages({t.name for t in bag.playable()}))
    recorder = Recorder(lambda name: BagWriter(workdir / name, storage, compression), queue_limit_bytes=2**40)
    for topic in bag.playable():
        recorder.add_topic(TopicSpec(topic.name, topic.msgtype, "", "", topic.offered_qos), True, False)
    recorder.start_bag("writer_only", T0)
    wall, cpu = time.perf_counter(), time.process_time()
    for k in range(repeats):
        for m in messages:
            recorder.put(m.topic, m.timestamp + k * 10**9, m.data)
    recorder.stop()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    shutil.rmtree(workdir / "writer_only")
    return repeats * sum(len(m.data) for m in messages) / wall / 1e6, 100.0 * cpu / wall


def _ros_run(executable: str, params: dict, env: dict, log: Path) -> subprocess.Popen:
    return start_logged(ros_run_command("actaim2_policy", executable, params), env, log)


def run_rate(source: Path, topics: list[str], rate: float, args: argparse.Namespace, workdir: Path) -> dict:
    env = private_ros_env()
    out = workdir / f"recorded_{rate:g}"
    recorder = _ros_run("bag_recorder", {
        "output": str(out), "storage": args.storage, "compression": args.compression,
        "topics": topics, "topic_patterns": [""], "summary_file": str(workdir / f"recorder_{rate:g}.json"),
        "report_period": 0.0, "discovery_period": 0.2,
    }, env, workdir / f"recorder_{rate:g}.log")
    player = _ros_run("bag_player", {
        "bag": str(source), "rate": rate, "loop": True, "wait_for_subscribers": topics, "start_delay": 1.0,
        "summary_file": str(workdir / f"player_{rate:g}.json"),
    }, env, workdir / f"player_{rate:g}.log")
    try:
        # The player starts once the recorder subscribed to every topic (wait_for_subscribers), + start_delay.
        recorder_log, deadline = workdir / f"recorder_{rate:g}.log", time.monotonic() + 60.0
        while not all(f"{t} [" in recorder_log.read_text() for t in topics):
            if time.monotonic() > deadline or recorder.poll() is not None or player.poll() is not None:
                raise RuntimeError(f"bag_recorder did not subscribe to every topic: {recorder_log.read_text()[-2000:]}")
            time.sleep(0.2)
        time.sleep(1.5)  # start_delay
        cpu0, wall0 = cpu_seconds(recorder.pid), time.monotonic()
        time.sleep(args.duration)
        cpu1, wall1 = cpu_seconds(recorder.pid), time.monotonic()
    finally:
        stop_group(player, timeout=60.0)
        time.sleep(1.0)  # the last messages reach the recorder
        stop_group(recorder, timeout=120.0)
    played = json.loads((workdir / f"player_{rate:g}.json").read_text())
    recorded = json.loads((workdir / f"recorder_{rate:g}.json").read_text())
    size = sum(p.stat().st_size for p in out.iterdir())
    info = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    return {"rate": rate, "played": played, "recorded": recorded, "cpu_pct": 100.0 * (cpu1 - cpu0) / (wall1 - wall0),
            "bag_bytes": size, "span_s": info["duration"]["nanoseconds"] / 1e9}


def _verdict(result: dict) -> tuple[bool, list[str]]:
    rows, ok = [], True
    for topic, published in sorted(result["played"]["published"].items()):
        counts = result["recorded"]["topics"].get(topic, {"recorded": 0, "reliable": True, "dropped": 0, "lost": 0})
        loss = 100.0 * (published - counts["recorded"]) / max(published, 1)
        target = 0.0 if counts["reliable"] else 1.0
        ok &= loss <= target
        rows.append(f"| {result['rate']:g} | {topic} | {'reliable' if counts['reliable'] else 'best effort'} | {published} | "
                    f"{counts['recorded']} | {counts['lost']} | {counts['dropped']} | {loss:.2f}% | {'ok' if loss <= target else 'MISSED'} |")
    return ok, rows


def main(args: argparse.Namespace) -> int:
    print(f"# bench bags ({os.cpu_count()} CPUs; load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())})")
    print("Shared machine: other jobs take CPU from the player and the recorder; figures are lower bounds.\n")
    workdir = args.workdir or Path(tempfile.mkdtemp(prefix="actaim2_bench_bags_"))
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        source = workdir / "ring5_source"
        if source.exists():
            shutil.rmtree(source)
        started = time.perf_counter()
        counts = make_source_bag(source, args.frames)
        print(f"source bag: {sum(counts.values())} messages, {sum(p.stat().st_size for p in source.iterdir()) / 1e6:.0f} MB "
              f"({args.frames} ring5 frames, looped), made in {time.perf_counter() - started:.1f} s\n")
        mbps, cpu = writer_only(source, args.storage, args.compression, workdir)
        print(f"recording pipeline alone (queue + writer thread + {args.storage} {args.compression}, no DDS): "
              f"{mbps:.0f} MB/s at {cpu:.0f}% CPU\n")
        topics = sorted(counts)
        results = []
        for rate in args.rates:
            result = run_rate(source, topics, rate, args, workdir)
            ok, rows = _verdict(result)
            results.append((result, ok, rows))
            if ok:
                break
        print("| rate | topic | QoS | published | recorded | lost in DDS | dropped (queue) | loss | target |")
        print("|---|---|---|---|---|---|---|---|---|")
        for _, _, rows in results:
            print("\n".join(rows))
        print("\n| rate | recorder MB/s | msgs/s | recorder CPU | bag on disk | player timing error p50 / p99 | targets |")
        print("|---|---|---|---|---|---|---|")
        for result, ok, _ in results:
            seconds = result["span_s"]  # first to last recorded message (receive times)
            recorded = result["recorded"]["topics"]
            mb = sum(c["bytes"] for c in recorded.values()) / 1e6
            msgs = sum(c["recorded"] for c in recorded.values())
            timing = result["played"]["timing_error_ms"]
            print(f"| {result['rate']:g} | {mb / seconds:.1f} | {msgs / seconds:.0f} | {result['cpu_pct']:.0f}% | "
                  f"{result['bag_bytes'] / 1e6:.0f} MB ({result['bag_bytes'] / max(mb * 1e6, 1):.2f} of raw, {args.compression}) | "
                  f"{timing.get('p50', float('nan')):.2f} / {timing.get('p99', float('nan')):.2f} ms | {'held' if ok else 'missed'} |")
        print(f"\nload average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    finally:
        if args.workdir is None:
            shutil.rmtree(workdir, ignore_errors=True)
    return 0
