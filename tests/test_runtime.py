"""actaim2.runtime: the defaults every rclpy process gets, and the two Fast DDS profiles it names."""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET

from actaim2.runtime import (
    DEFAULT_DISCOVERY_RANGE,
    DISCOVERY_RANGE_VAR,
    FASTDDS_PROFILE,
    FASTDDS_PROFILE_VAR,
    FASTDDS_UDP_PROFILE,
    apply_ros_defaults,
)

NS = {"p": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}


def _transports(profile) -> tuple[list[ET.Element], str]:
    root = ET.parse(profile).getroot()
    participant = root.find("p:participant[@is_default_profile='true']/p:rtps", NS)
    used = {t.text for t in participant.findall("p:userTransports/p:transport_id", NS)}
    descriptors = [d for d in root.findall("p:transport_descriptors/p:transport_descriptor", NS)
                   if d.findtext("p:transport_id", namespaces=NS) in used]
    return descriptors, participant.findtext("p:useBuiltinTransports", namespaces=NS)


def test_defaults_are_set_only_where_the_user_chose_nothing(monkeypatch) -> None:
    monkeypatch.delenv(DISCOVERY_RANGE_VAR, raising=False)
    monkeypatch.setenv(FASTDDS_PROFILE_VAR, "/my/own.xml")
    apply_ros_defaults()
    assert os.environ[DISCOVERY_RANGE_VAR] == DEFAULT_DISCOVERY_RANGE == "LOCALHOST"
    assert os.environ[FASTDDS_PROFILE_VAR] == "/my/own.xml"


def test_the_default_profile_adds_a_32_mb_shared_memory_segment_to_the_builtin_transports() -> None:
    descriptors, builtin = _transports(FASTDDS_PROFILE)
    assert builtin == "true"
    assert [(d.findtext("p:type", namespaces=NS), d.findtext("p:segment_size", namespaces=NS)) for d in descriptors] == \
        [("SHM", str(32 * 1024 * 1024))]


def test_the_crash_restart_profile_is_udp_on_loopback_only_without_shared_memory() -> None:
    descriptors, builtin = _transports(FASTDDS_UDP_PROFILE)
    assert builtin == "false"  # no builtin SHM either
    assert [d.findtext("p:type", namespaces=NS) for d in descriptors] == ["UDPv4"]
    assert [a.text for a in descriptors[0].findall("p:interfaceWhiteList/p:address", NS)] == ["127.0.0.1"]
