"""The demonstrations in a recorded bag: per episode, its marked keyposes and the clouds around them.

A teleop bag (``bag_recorder`` while ``teleop_node`` or ``scripted_teleop`` runs) holds the
camera clouds, ``/tf_static``, ``/joint_states``, every marked keypose on ``/keypose``, the mode
label on ``/interaction_mode`` and START / END on ``/episode``. Messages are read once, in the
order they were recorded, and each episode (START .. END of the same episode number) gives

* the keyposes: the last marking of each phase INIT, REACH, GRASP, MANIPULATE (a keypose that
  failed and was marked again appears twice: the later one counts), in this order;
* the observations, each a *set* of clouds, the latest of every rig camera received since START:
  ``init`` the first complete set after START, ``o<i>`` the set when keypose i was marked
  (O_i is taken before a_i executes), ``final`` the set when END arrived;
* the operator's verdict (END's ``success``), the mode label in use at END and the object id.

An episode is handed on once ``/joint_states`` reach past its last cloud (or the bag ends), so
the robot can be posed at every cloud's stamp by interpolation.

Required: ``/tf_static``, ``/joint_states``, ``/keypose``, ``/episode`` and the rig's cloud topics
(``/points2`` for ``azure_kinect``). A bag lacking one is a :class:`BagProblem` (the caller
reports it and skips the bag); an episode lacking a keypose, a cloud set or its END is reported
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
from actaim2.perception.joint_history import JointStateHistory
from actaim2.perception.static_tf import StaticTransformBuffer

BASE_TOPICS = ("/tf_static", "/joint_states", "/keypose", "/episode")
MODE_TOPIC = "/interaction_mode"
EPISODE_START, EPISODE_END = 0, 1  # EpisodeEvent.START / END
ALL_OF_IT = 1e6  # s of joint-state history kept: a whole bag (the history only grows with the bag)


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
    joints: JointStateHistory  # /joint_states of the bag, at least up to the episode's last cloud when possible
    transforms: StaticTransformBuffer

    @property
    def last_stamp_ns(self) -> int:
        return max(c.stamp_ns for clouds in self.observations.values() for c in clouds.values())


@dataclass
class _Open:
    """An episode between its START and its END."""

    episode: int
    object_id: str
    latest: dict[str, object] = field(default_factory=dict)  # camera -> latest raw cloud message since START
    init: dict[str, object] | None = None
    marked: dict[int, tuple[int, Keypose, dict[str, object] | None]] = field(default_factory=dict)  # phase -> (order, keypose, set)
    order: int = 0


def _stamp(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


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
    return Cloud(camera, _stamp(msg.header), msg.header.frame_id, decoded.xyz.reshape(shape), rgb)


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
        present = sorted(source.topics)
        raise BagProblem(f"{path}: missing required topic(s) {missing} (the bag has {present})")
    topics = set(required) | ({MODE_TOPIC} & playable)
    tf, joints = StaticTransformBuffer(), JointStateHistory(history=ALL_OF_IT)
    label, current = "", None
    pending: list[BagEpisode] = []  # closed, waiting until /joint_states reach past their last cloud
    for message in source.messages(topics):
        msg = source.deserialize(message)
        topic = message.topic
        if topic == "/tf_static":
            for t in msg.transforms:
                r, p = t.transform.rotation, t.transform.translation
                tf.set_transform(t.header.frame_id, t.child_frame_id, pose_to_matrix([p.x, p.y, p.z], [r.x, r.y, r.z, r.w]))
        elif topic == "/joint_states":
            joints.add(_stamp(msg.header), list(msg.name), list(msg.position))
            while pending and joints.covers(pending[0].last_stamp_ns):
                yield pending.pop(0)
        elif topic == MODE_TOPIC:
            label = str(msg.label)
        elif topic == "/episode":
            if msg.event == EPISODE_START:
                if current is not None:
                    report(f"{path}: episode {current.episode}: no END before the START of episode {msg.episode}; skipped")
                current = _Open(int(msg.episode), str(msg.object_id))
            elif msg.event == EPISODE_END:
                if current is None or current.episode != int(msg.episode):
                    report(f"{path}: END of episode {msg.episode} without its START; skipped")
                    current = None
                    continue
                episode = _close(path, current, msg, label, joints, tf, cameras, report)
                current = None
                if episode is not None:
                    pending.append(episode)
        elif current is None:
            continue  # clouds and keyposes outside an episode are not part of a demonstration
        elif topic == "/keypose":
            keypose = _keypose(msg)
            if not 0 <= keypose.phase < len(PHASE_NAMES):
                report(f"{path}: episode {current.episode}: keypose of unknown phase {keypose.phase} ignored")
                continue
            complete = len(current.latest) == len(cameras)
            current.marked[keypose.phase] = (current.order, keypose, dict(current.latest) if complete else None)
            current.order += 1
        else:
            current.latest[cameras[topic]] = msg
            if current.init is None and len(current.latest) == len(cameras):
                current.init = dict(current.latest)
    if current is not None:
        report(f"{path}: episode {current.episode}: the bag ends before its END; skipped")
    yield from pending


def _close(path: Path, current: _Open, end, label: str, joints: JointStateHistory, tf: StaticTransformBuffer,
           cameras: dict[str, str], report: Callable[[str], None]) -> BagEpisode | None:
    """The finished episode, or None (reported) when it lacks a keypose or a cloud set."""
    where = f"{path}: episode {current.episode}"
    missing = [PHASE_NAMES[p] for p in range(len(PHASE_NAMES)) if p not in current.marked]
    if missing:
        report(f"{where}: no keypose marked for {', '.join(missing)}; skipped")
        return None
    orders = [current.marked[p][0] for p in range(len(PHASE_NAMES))]
    if orders != sorted(orders):
        report(f"{where}: keyposes marked out of order (last markings in the order "
               f"{[PHASE_NAMES[p] for p in np.argsort(orders)]}); skipped")
        return None
    sets = {"init": current.init, **{f"o{p}": current.marked[p][2] for p in range(len(PHASE_NAMES))}}
    sets["final"] = dict(current.latest) if len(current.latest) == len(cameras) else None
    empty = [name for name, s in sets.items() if s is None]
    if empty:
        report(f"{where}: no complete set of clouds ({sorted(cameras)}) for observation(s) {empty} "
               f"(clouds are taken from START on); skipped")
        return None
    try:
        observations = {name: {camera: decode_cloud(camera, msg) for camera, msg in s.items()} for name, s in sets.items()}
    except CloudFormatError as exc:
        report(f"{where}: {exc}; skipped")
        return None
    return BagEpisode(path, current.episode, current.object_id, bool(end.success), str(end.note), label,
                      [current.marked[p][1] for p in range(len(PHASE_NAMES))], observations, joints, tf)
