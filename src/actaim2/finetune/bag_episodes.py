"""The demonstrations in a recorded bag: per episode, its marked keyposes and the clouds around them.

A teleop bag (``bag_recorder`` while ``teleop_node`` or ``scripted_teleop`` runs) holds the
camera clouds, ``/tf_static``, ``/joint_states``, every marked keypose on ``/keypose``, the mode
label on ``/interaction_mode`` and START / END on ``/episode``. Each episode (START .. END of the
same episode number, in recording order) gives

* the keyposes: the last marking of each phase INIT, REACH, GRASP, MANIPULATE (a keypose that
  failed and was marked again appears twice: the later one counts), in this order;
* the observations, one cloud per rig camera each, chosen by header stamp among the clouds
  of the episode (below) stamped at or after START (earlier ones may show the scene
  before its reset): ``init`` the first, ``o<i>`` the latest stamped at or before keypose i
  (O_i is what was seen when a_i was marked, before it executed), ``final`` the latest stamped
  at or before END. INIT is often marked at START itself, before the first cloud of a bag split
  by episode: O_0 is then the first cloud, if it precedes REACH's marking (INIT moves only the
  arm, never the object, so that cloud shows the scene INIT was chosen from; the arm in it is
  removed from the views with its joint positions at that stamp);
* the operator's verdict (END's ``success``), the mode label in use at END and the object id.

What an episode holds: the keyposes and clouds recorded between its START and END, and those
recorded between the previous END (or the bag's beginning) and its START that are stamped at or
after START. Topics reach the recorder in no fixed order, so the INIT keypose published right
after START can be received (and logged) just before it; bag_recorder's episode bags therefore
begin up to its ``start_grace`` before START, and the stamp tells the new episode's messages
from those of the reset scene before it.

Stamps, not recording order, decide: a keypose is recorded as soon as it is sent, the cloud the
operator saw may reach the recorder after it (a 3 MB message), and a bag split by episode starts
at (or just before) START. All header stamps are on one clock (sim time under ``use_sim_time``).

The bag is read twice: first everything but the clouds' points (stamps, keyposes, joint states,
transforms), then only the chosen clouds are decoded, an episode being handed on as soon as its
clouds are, so memory holds one episode's clouds whatever the bag's length.

Required: ``/tf_static``, ``/joint_states``, ``/keypose``, ``/episode`` and the rig's cloud topics
(``/points2`` for ``azure_kinect``). A bag lacking one is a :class:`BagProblem` (the caller
reports it and skips the bag); an episode lacking a keypose, a cloud or its END is reported
and skipped, the bag's other episodes are kept. ``/interaction_mode`` is optional (label "").
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from actaim2.bags.source import BagSource
from actaim2.geometry import pose_to_matrix
from actaim2.keypose import PHASE_NAMES, Keypose
from actaim2.perception.cloud_codec import CloudFormatError, Field, decode
from actaim2.perception.joint_history import DEFAULT_MAX_EXTRAPOLATION, JointStateHistory
from actaim2.perception.static_tf import StaticTransformBuffer
from actaim2.stamps import header_stamp_ns

BASE_TOPICS = ("/tf_static", "/joint_states", "/keypose", "/episode")
MODE_TOPIC = "/interaction_mode"
EPISODE_START, EPISODE_END = 0, 1  # EpisodeEvent.START / END
ALL_OF_IT = 1e6  # s of joint-state history kept: a whole bag
HOLD_BACK_NS = int(DEFAULT_MAX_EXTRAPOLATION * 1e9)  # a cloud this much older than the first joint state takes it


class BagProblem(ValueError):
    """The bag as a whole cannot give demonstrations (a required topic is missing or unreadable)."""


@dataclass(frozen=True)
class Cloud:
    """One organized cloud as recorded, decoded."""

    camera: str  # the rig's camera name
    stamp_ns: int  # header stamp: when the sensor took it
    frame_id: str
    xyz: np.ndarray  # (H, W, 3) float32 in frame_id, NaN = no return
    rgb: np.ndarray | None  # (H, W, 3) uint8, None for xyz-only clouds


@dataclass
class BagEpisode:
    bag: Path
    episode: int  # EpisodeEvent.episode
    object_id: str
    success: bool  # the operator's verdict at END
    note: str
    label: str  # the mode label in use at END ("" without /interaction_mode)
    keyposes: list[Keypose]  # INIT, REACH, GRASP, MANIPULATE
    observations: dict[str, dict[str, Cloud]]  # "init", "o0".."o3", "final" -> camera -> cloud
    joints: JointStateHistory  # every /joint_states of the bag
    first_joints_ns: int  # stamp of the bag's first /joint_states
    transforms: StaticTransformBuffer

    def joints_at(self, stamp_ns: int) -> dict[str, float]:
        """Joint positions at a cloud's stamp (JointStateUnavailable when unknown there). A bag split by
        episode starts at START, often with a cloud a few ms before its first joint state: within
        the history's extrapolation bound that first state is used, as the history extrapolates forward."""
        if self.first_joints_ns - HOLD_BACK_NS <= stamp_ns < self.first_joints_ns:
            stamp_ns = self.first_joints_ns
        return self.joints.at(stamp_ns)


CloudRef = tuple[str, int]  # (topic, index among the topic's messages)


@dataclass
class _Episode:
    """What the first pass learns of one episode."""

    episode: int
    object_id: str
    start_ns: int
    marked: dict[int, tuple[int, Keypose, int]] = field(default_factory=dict)  # phase -> (marking number, keypose, stamp)
    markings: int = 0
    clouds: list[tuple[str, int, int]] = field(default_factory=list)  # (topic, index, stamp) recorded in the episode
    chosen: dict[str, dict[str, CloudRef]] = field(default_factory=dict)  # observation -> camera -> cloud
    end: tuple[bool, str, str] | None = None  # success, note, label


def _keypose(msg) -> Keypose:
    p, q = msg.pose.position, msg.pose.orientation
    return Keypose(int(msg.phase), np.array([p.x, p.y, p.z], float), np.array([q.x, q.y, q.z, q.w], float), bool(msg.gripper_closed))


def decode_cloud(camera: str, msg) -> Cloud:
    """A rosbags PointCloud2 -> :class:`Cloud`; CloudFormatError for unorganized or unreadable ones."""
    if msg.height < 2:
        raise CloudFormatError(f"cloud of {camera} is unorganized ({msg.width}x{msg.height}): intrinsics need an image grid")
    fields = [Field(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    decoded = decode(fields, bytes(msg.data), msg.height, msg.width, msg.point_step, msg.row_step, msg.is_bigendian)
    shape = (decoded.height, decoded.width, 3)
    rgb = None if decoded.rgb is None else decoded.rgb.reshape(shape)
    return Cloud(camera, header_stamp_ns(msg.header), msg.header.frame_id, decoded.xyz.reshape(shape), rgb)


def choose_clouds(ep: _Episode, end_ns: int, cameras: dict[str, str]) -> dict[str, dict[str, CloudRef]]:
    """Per observation and camera, the cloud it is made of (module docstring); ValueError saying
    which observation has none."""
    chosen: dict[str, dict[str, CloudRef]] = {}
    moments = {f"o{p}": ep.marked[p][2] for p in range(len(PHASE_NAMES))} | {"final": end_ns}
    for topic, camera in cameras.items():
        series = sorted((stamp, index) for t, index, stamp in ep.clouds if t == topic and ep.start_ns <= stamp <= end_ns)
        if not series:
            raise ValueError(f"no {topic} cloud stamped between START ({ep.start_ns / 1e9:.3f} s) and END "
                             f"({end_ns / 1e9:.3f} s) (are the clouds and the teleoperator on one clock?)")
        chosen.setdefault("init", {})[camera] = (topic, series[0][1])
        for name, moment in moments.items():
            before = [index for stamp, index in series if stamp <= moment]
            if not before and name == "o0" and series[0][0] < ep.marked[1][2]:
                before = [series[0][1]]  # INIT marked at START, before the first cloud
            if not before:
                raise ValueError(f"no {topic} cloud stamped between START and {name} ({moment / 1e9:.3f} s)")
            chosen.setdefault(name, {})[camera] = (topic, before[-1])
    return chosen


def read_episodes(path: str | Path, cameras: dict[str, str], report: Callable[[str], None]) -> Iterator[BagEpisode]:
    """Episodes of the bag at ``path``, in recording order; ``cameras`` maps cloud topics to camera
    names (the rig's). Problems of single episodes go to ``report``; a bag that cannot give any
    raises :class:`BagProblem` before the first episode."""
    path = Path(path)
    try:
        source = BagSource(path, lambda text: report(f"{path}: {text}"))
    except (FileNotFoundError, OSError) as exc:
        raise BagProblem(f"{path}: cannot be opened ({exc})") from exc
    playable = {t.name for t in source.playable()}
    required = list(BASE_TOPICS) + list(cameras)
    missing = [t for t in required if t not in playable]
    if missing:
        raise BagProblem(f"{path}: missing required topic(s) {missing} (the bag has {sorted(source.topics)})")
    tf, joints = StaticTransformBuffer(), JointStateHistory(history=ALL_OF_IT)
    episodes, first_joints_ns = _first_pass(path, source, set(required) | ({MODE_TOPIC} & playable), cameras, tf, joints, report)
    yield from _second_pass(path, source, episodes, cameras, tf, joints, first_joints_ns, report)


def _first_pass(path: Path, source: BagSource, topics: set[str], cameras: dict[str, str], tf: StaticTransformBuffer,
                joints: JointStateHistory, report: Callable[[str], None]) -> tuple[list[_Episode], int]:
    """(episodes whose keyposes and clouds are complete, with their clouds chosen; the first joint
    state's stamp); fills tf and joints."""
    label, current, done, first_joints_ns = "", None, [], None
    waiting: list[tuple[str, int, int, Keypose | None]] = []  # keyposes and clouds recorded while no episode is open
    for message in source.messages(topics):
        msg = source.deserialize(message)
        topic = message.topic
        if topic == "/tf_static":
            for t in msg.transforms:
                r, p = t.transform.rotation, t.transform.translation
                tf.set_transform(t.header.frame_id, t.child_frame_id, pose_to_matrix([p.x, p.y, p.z], [r.x, r.y, r.z, r.w]))
        elif topic == "/joint_states":
            joints.add(header_stamp_ns(msg.header), list(msg.name), list(msg.position))
            first_joints_ns = header_stamp_ns(msg.header) if first_joints_ns is None else first_joints_ns
        elif topic == MODE_TOPIC:
            label = str(msg.label)
        elif topic == "/episode":
            if msg.event == EPISODE_START:
                if current is not None:
                    report(f"{path}: episode {current.episode}: no END before the START of episode {msg.episode}; skipped")
                current = _Episode(int(msg.episode), str(msg.object_id), header_stamp_ns(msg.header))
                for item in waiting:
                    if item[2] >= current.start_ns:
                        _take(path, current, item, report)
                waiting.clear()
            elif msg.event == EPISODE_END:
                if current is None or current.episode != int(msg.episode):
                    report(f"{path}: END of episode {msg.episode} without its START; skipped")
                elif _close(path, current, msg, label, cameras, report):
                    done.append(current)
                current = None
                waiting.clear()
        else:  # a keypose or a cloud
            item = (topic, message.index, header_stamp_ns(msg.header), _keypose(msg) if topic == "/keypose" else None)
            if current is None:
                waiting.append(item)  # part of the next episode if stamped at or after its START
            else:
                _take(path, current, item, report)
    if current is not None:
        report(f"{path}: episode {current.episode}: the bag ends before its END; skipped")
    return done, first_joints_ns if first_joints_ns is not None else 0


def _take(path: Path, ep: _Episode, item: tuple[str, int, int, Keypose | None], report: Callable[[str], None]) -> None:
    """Add a keypose marking or a cloud (topic, index, header stamp, keypose or None) to the episode."""
    topic, index, stamp, keypose = item
    if keypose is None:
        ep.clouds.append((topic, index, stamp))
    elif not 0 <= keypose.phase < len(PHASE_NAMES):
        report(f"{path}: episode {ep.episode}: keypose of unknown phase {keypose.phase} ignored")
    else:
        ep.marked[keypose.phase] = (ep.markings, keypose, stamp)
        ep.markings += 1


def _close(path: Path, ep: _Episode, end, label: str, cameras: dict[str, str], report: Callable[[str], None]) -> bool:
    """Check the finished episode and choose its clouds; False (reported) when it cannot be used."""
    where = f"{path}: episode {ep.episode}"
    missing = [PHASE_NAMES[p] for p in range(len(PHASE_NAMES)) if p not in ep.marked]
    if missing:
        report(f"{where}: no keypose marked for {', '.join(missing)}; skipped")
        return False
    orders = [ep.marked[p][0] for p in range(len(PHASE_NAMES))]
    if orders != sorted(orders):
        report(f"{where}: keyposes marked out of order (last markings in the order "
               f"{[PHASE_NAMES[p] for p in np.argsort(orders)]}); skipped")
        return False
    try:
        ep.chosen = choose_clouds(ep, header_stamp_ns(end.header), cameras)
    except ValueError as exc:
        report(f"{where}: {exc}; skipped")
        return False
    ep.end = (bool(end.success), str(end.note), label)
    return True


def _second_pass(path: Path, source: BagSource, episodes: list[_Episode], cameras: dict[str, str],
                 tf: StaticTransformBuffer, joints: JointStateHistory, first_joints_ns: int,
                 report: Callable[[str], None]) -> Iterator[BagEpisode]:
    """Decode the chosen clouds in one read, handing each episode on once its clouds are decoded."""
    wanted = {ref for ep in episodes for clouds in ep.chosen.values() for ref in clouds.values()}
    decoded: dict[CloudRef, Cloud | str] = {}  # a str: why that cloud cannot be used
    pending = list(episodes)

    def ready(ep: _Episode) -> bool:
        return all(ref in decoded for clouds in ep.chosen.values() for ref in clouds.values())

    def finish(ep: _Episode) -> BagEpisode | None:
        problems = {decoded.get(ref, f"{ref[0]} message {ref[1]} could not be read")
                    for clouds in ep.chosen.values() for ref in clouds.values() if not isinstance(decoded.get(ref), Cloud)}
        if problems:
            report(f"{path}: episode {ep.episode}: {'; '.join(sorted(problems))}; skipped")
            return None
        success, note, label = ep.end
        return BagEpisode(path, ep.episode, ep.object_id, success, note, label,
                          [ep.marked[p][1] for p in range(len(PHASE_NAMES))],
                          {name: {camera: decoded[ref] for camera, ref in clouds.items()} for name, clouds in ep.chosen.items()},
                          joints, first_joints_ns, tf)

    for message in source.messages(set(cameras)) if wanted else ():
        ref = (message.topic, message.index)
        if ref not in wanted:
            continue
        try:
            decoded[ref] = decode_cloud(cameras[message.topic], source.deserialize(message))
        except CloudFormatError as exc:
            decoded[ref] = str(exc)
        while pending and ready(pending[0]):
            episode = finish(pending.pop(0))
            if episode is not None:
                yield episode
            _forget(decoded, pending)
    for ep in pending:  # clouds that did not come back on the second read (a file damaged between the reads)
        episode = finish(ep)
        if episode is not None:
            yield episode


def _forget(decoded: dict[CloudRef, Cloud | str], pending: list[_Episode]) -> None:
    """Drop the decoded clouds no pending episode uses."""
    used = {ref for ep in pending for clouds in ep.chosen.values() for ref in clouds.values()}
    for ref in [r for r in decoded if r not in used]:
        del decoded[ref]
