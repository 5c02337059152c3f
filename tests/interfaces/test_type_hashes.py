"""The workspace's interface definitions hash the way rosidl and ROS 2 Jazzy hash them.

A RIHS01 type hash travels with every endpoint during discovery and is written into every
rosbag2 file: a bag recorded here must open on a real ROS 2 install and the nodes here must talk
to real drivers. Each definition is therefore hashed twice, by rosbags from the .msg/.srv/.action
text and by the type support rclpy loads, and the two must agree; for the interfaces the
workspace provides itself (compat/), the texts and hashes must also equal the ROS 2 Jazzy ones.
"""
from __future__ import annotations

import functools
import json
from pathlib import Path

import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from harness import REPO, wait_for
from interface_types import (
    generated_classes,
    interface_files,
    jazzy_typestore,
    jazzy_typestore_with,
    rclpy_type_hash,
)

ACTAIM2_MSGS = REPO / "actaim2_msgs"
CONTROL_MSGS = REPO / "compat" / "control_msgs"
RELEASED_CONTROL_MSGS = Path(__file__).parent / "released" / "control_msgs"


def _ids(files: list[tuple[str, str, Path]]) -> list[str]:
    return [f"{kind}/{name}" for kind, name, _ in files]


@functools.cache
def _store_with(package: str, package_dir: Path) -> Typestore:
    return jazzy_typestore_with(package, package_dir)


def _assert_hashes_match(package: str, package_dir: Path, kind: str, name: str) -> None:
    store = _store_with(package, package_dir)
    hashes = {typename: (store.hash_rihs01(typename), rclpy_type_hash(cls))
              for typename, cls in generated_classes(package, kind, name).items()}
    mismatched = {typename: pair for typename, pair in hashes.items() if pair[0] != pair[1]}
    assert not mismatched, f"(rosbags, rclpy) hashes differ: {mismatched}"


@pytest.mark.parametrize(("kind", "name", "path"), interface_files(ACTAIM2_MSGS), ids=_ids(interface_files(ACTAIM2_MSGS)))
def test_actaim2_msgs_hash_like_rclpy(kind: str, name: str, path: Path) -> None:
    """Every type generated from an actaim2_msgs file (parts, service events, action services)."""
    _assert_hashes_match("actaim2_msgs", ACTAIM2_MSGS, kind, name)


def test_every_actaim2_interface_is_checked() -> None:
    """The parametrization above sees all eight interfaces of DESIGN.md."""
    assert set(_ids(interface_files(ACTAIM2_MSGS))) >= {
        "msg/Keypose", "msg/OrthoViews", "msg/InteractionMode", "msg/EpisodeEvent",
        "srv/SampleMode", "srv/PredictKeypose", "srv/ResetScene", "action/ExecuteKeypose",
    }


def test_a_changed_field_changes_the_hash() -> None:
    """The comparison can fail: one renamed field gives another hash than rclpy's Keypose."""
    from actaim2_msgs.msg import Keypose

    text = (ACTAIM2_MSGS / "msg" / "Keypose.msg").read_text().replace("bool gripper_closed", "bool gripper_open")
    store = jazzy_typestore()
    store.register(get_types_from_msg(text, "actaim2_msgs/msg/Keypose"))
    assert store.hash_rihs01("actaim2_msgs/msg/Keypose") != rclpy_type_hash(Keypose)


def test_tf2_msgs_is_ros2_jazzy_tfmessage() -> None:
    """The workspace's TFMessage (compat build or underlay) hashes like rosbags' ROS2_JAZZY one."""
    from tf2_msgs.msg import TFMessage

    jazzy_hash = get_typestore(Stores.ROS2_JAZZY).hash_rihs01("tf2_msgs/msg/TFMessage")
    assert rclpy_type_hash(TFMessage) == jazzy_hash
    compat_text = (REPO / "compat" / "tf2_msgs" / "msg" / "TFMessage.msg").read_text()
    store = get_typestore(Stores.ROS2_JAZZY)
    assert store.fielddefs["tf2_msgs/msg/TFMessage"] == get_types_from_msg(compat_text, "tf2_msgs/msg/TFMessage")["tf2_msgs/msg/TFMessage"]


def test_control_msgs_files_are_the_provided_set() -> None:
    """compat/control_msgs carries exactly the released files kept as fixtures."""
    provided = {path.relative_to(CONTROL_MSGS) for _, _, path in interface_files(CONTROL_MSGS)}
    released = {path.relative_to(RELEASED_CONTROL_MSGS) for _, _, path in interface_files(RELEASED_CONTROL_MSGS)}
    assert provided == released == {
        Path("action/FollowJointTrajectory.action"), Path("action/GripperCommand.action"),
        Path("msg/GripperCommand.msg"), Path("msg/JointComponentTolerance.msg"), Path("msg/JointTolerance.msg"),
    }


@pytest.mark.parametrize(("kind", "name", "path"), interface_files(RELEASED_CONTROL_MSGS), ids=_ids(interface_files(RELEASED_CONTROL_MSGS)))
def test_control_msgs_text_is_the_jazzy_release(kind: str, name: str, path: Path) -> None:
    """Byte for byte, comments and trailing newline included."""
    assert (CONTROL_MSGS / kind / path.name).read_bytes() == path.read_bytes()


@pytest.mark.parametrize(("kind", "name", "path"), interface_files(CONTROL_MSGS), ids=_ids(interface_files(CONTROL_MSGS)))
def test_control_msgs_hash_like_rclpy(kind: str, name: str, path: Path) -> None:
    _assert_hashes_match("control_msgs", CONTROL_MSGS, kind, name)


def test_control_msgs_hashes_are_the_jazzy_build_hashes() -> None:
    """rclpy's control_msgs types report the hashes a ROS 2 Jazzy build of control_msgs has."""
    reference = json.loads((RELEASED_CONTROL_MSGS / "type_hashes.json").read_text())["hashes"]
    reported = {}
    for kind, name, _ in interface_files(CONTROL_MSGS):
        reported |= {typename: rclpy_type_hash(cls) for typename, cls in generated_classes("control_msgs", kind, name).items()}
    assert {typename: reported[typename] for typename in reference} == reference


def test_hash_reader_agrees_with_rclpy_discovery(ros_node) -> None:
    """The type-support hash read here is the one rclpy reports for a live publisher."""
    from actaim2_msgs.msg import Keypose
    from control_msgs.msg import JointTolerance

    for cls, topic in ((Keypose, "/type_hash_probe/keypose"), (JointTolerance, "/type_hash_probe/joint_tolerance")):
        ros_node.create_publisher(cls, topic, 1)
        assert wait_for(lambda: bool(ros_node.get_publishers_info_by_topic(topic)), timeout=5.0)
        (info,) = ros_node.get_publishers_info_by_topic(topic)
        assert str(info.topic_type_hash) == rclpy_type_hash(cls)
