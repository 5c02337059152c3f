"""Our metadata.yaml and message definitions against files the real rosbag2 wrote
(../shared/bags-reference: Jazzy `ros2 bag record`, rosbag2's own test resources)."""
from __future__ import annotations

import pytest
import yaml
from mcap.reader import make_reader

from actaim2.bags import yaml_emit
from actaim2.bags.definitions import SEPARATOR
from actaim2.bags.writer import BagWriter
from bagtools import DEFINITIONS, REFERENCE, joint_state, spec, tf_static

JAZZY_MCAP = REFERENCE / "jazzy_mcap_abitobot"
V9_MCAP = REFERENCE / "reference_metadata" / "rosbag2_rolling_2025-03_v9_mcap_metadata.yaml"
V9_SQLITE = REFERENCE / "reference_metadata" / "rosbag2_rolling_2025-03_v9_sqlite3_metadata.yaml"


@pytest.mark.parametrize("path", [
    JAZZY_MCAP / "metadata.yaml",
    V9_SQLITE,
    REFERENCE / "rosbag2_v8_mcap_topics_services" / "metadata.yaml",
    REFERENCE / "rosbag2_v8_sqlite3_topics_services" / "metadata.yaml",
], ids=lambda p: p.parent.name if p.name == "metadata.yaml" else p.stem)
def test_emitter_rewrites_rosbag2_metadata_byte_for_byte(path):
    text = path.read_text()
    assert yaml_emit.dump(yaml.safe_load(text), final_newline=text.endswith("\n")) == text


def key_paths(node, path=""):
    """Every key path in document order with the YAML type of its value (list items merged)."""
    out = []
    if isinstance(node, dict):
        for key, value in node.items():
            out.append((f"{path}/{key}", type(value).__name__))
            out += key_paths(value, f"{path}/{key}")
    elif isinstance(node, list):
        seen = []
        for item in node:
            for entry in key_paths(item, f"{path}[]"):
                if entry not in seen:
                    seen.append(entry)
        out += seen
    return out


def write_small_bag(path, storage):
    writer = BagWriter(path, storage, "lz4" if storage == "mcap" else "none")
    topic = writer.add_topic(spec("/joint_states", "sensor_msgs/msg/JointState"))
    latched = writer.add_topic(spec("/tf_static", "tf2_msgs/msg/TFMessage", latched=True))
    writer.write(latched, 10**18, tf_static("camera"))
    for i in range(5):
        writer.write(topic, 10**18 + i * 10**7, joint_state(i))
    writer.close()
    return yaml.safe_load((path / "metadata.yaml").read_text())


@pytest.mark.parametrize("storage, references", [
    ("mcap", [JAZZY_MCAP / "metadata.yaml", V9_MCAP]),
    ("sqlite3", [V9_SQLITE]),
])
def test_our_metadata_has_the_keys_of_the_reference_bags(tmp_path, storage, references):
    ours = write_small_bag(tmp_path / "bag", storage)
    info = ours["rosbag2_bagfile_information"]
    for reference in references:
        theirs = yaml.safe_load(reference.read_text())
        assert key_paths(ours) == key_paths(theirs), reference
        ref_info = theirs["rosbag2_bagfile_information"]
        assert (info["version"], info["storage_identifier"]) == (ref_info["version"], ref_info["storage_identifier"])
        assert info["compression_format"] == ref_info["compression_format"] == ""
        for entry in info["topics_with_message_count"] + ref_info["topics_with_message_count"]:
            qos = entry["topic_metadata"]["offered_qos_profiles"]
            assert all(q["history"] == "unknown" and q["reliability"] in ("reliable", "best_effort") for q in qos)
    by_topic = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert by_topic["/tf_static"]["topic_metadata"]["offered_qos_profiles"][0]["durability"] == "transient_local"
    assert by_topic["/joint_states"]["message_count"] == 5 and info["message_count"] == 6
    assert info["relative_file_paths"] == [f"bag_0.{'mcap' if storage == 'mcap' else 'db3'}"]


def test_our_message_definitions_are_the_ones_ros2_bag_record_stores():
    """Section by section as Jazzy stored them; builtin_interfaces/Time's comments changed
    between releases (ours: the installed wheel), so that section compares field lines only."""
    with open(next(JAZZY_MCAP.glob("*.mcap")), "rb") as f:
        summary = make_reader(f).get_summary()
    channels = {c.schema_id: c for c in summary.channels.values()}
    for schema in summary.schemas.values():
        ours = DEFINITIONS.definition(schema.name).split(SEPARATOR)
        theirs = schema.data.decode().split(SEPARATOR)
        assert [s.partition("\n")[0] for s in ours[1:]] == [s.partition("\n")[0] for s in theirs[1:]]  # same dependencies, same order
        for a, b in zip(ours, theirs):
            if "MSG: builtin_interfaces/Time" in a:
                fields = lambda s: [x for x in s.splitlines() if x and not x.startswith("#")]  # noqa: E731
                assert fields(a) == fields(b)
            else:
                assert a == b
        assert DEFINITIONS.type_hash(schema.name) == channels[schema.id].metadata["topic_type_hash"]
