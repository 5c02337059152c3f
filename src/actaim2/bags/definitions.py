"""Message definitions and type hashes of installed ROS 2 interface packages, as rosbag2 stores them.

rosbag2 (``LocalMessageDefinitionSource``) writes each topic's type as the original .msg text
(comments included) followed, depth first, by every dependency not written yet:
``"\\n" + "=" * 80 + "\\nMSG: pkg/Name\\n" + text``, dependencies of one file in sorted order.
Doing the same here makes our schemas byte-identical to those of ``ros2 bag record``
(tests/bags/test_definitions.py compares with a Jazzy bag), so every reader that parses theirs
parses ours. The type hash (RIHS01) comes from the ``.json`` type description rosidl installs
next to each .msg.

Types are found under ``<prefix>/share/<package>/msg/`` for each prefix of AMENT_PREFIX_PATH
(passed in: this module does not read the environment).
"""
from __future__ import annotations

import json
import re
from functools import lru_cache
from pathlib import Path
from typing import Sequence

SEPARATOR = "=" * 80 + "\n"
# rosbag2's MSG_FIELD_TYPE_REGEX: the type token at the start of a field line, array suffix allowed.
_FIELD_TYPE = re.compile(r"^\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+", re.MULTILINE)
_PRIMITIVES = {
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
    "int32", "uint32", "int64", "uint64", "string", "wstring", "time", "duration",
}


class UnknownMessageType(LookupError):
    """No installed package provides this message type's .msg file."""


def split_type(msgtype: str) -> tuple[str, str, str]:
    """"pkg/msg/Name" (or "pkg/Name") -> (pkg, "msg", Name)."""
    parts = msgtype.split("/")
    if len(parts) == 3:
        return parts[0], parts[1], parts[2]
    if len(parts) == 2:
        return parts[0], "msg", parts[1]
    raise UnknownMessageType(f"'{msgtype}' is not a message type name (expected pkg/msg/Name)")


class MessageDefinitions:
    """Looks up .msg texts and type hashes in the share folders of the given install prefixes."""

    def __init__(self, prefixes: Sequence[str | Path]) -> None:
        self._prefixes = [Path(p) for p in prefixes if str(p)]
        self.definition = lru_cache(maxsize=None)(self._definition)

    def _file(self, msgtype: str, suffix: str) -> Path:
        package, kind, name = split_type(msgtype)
        for prefix in self._prefixes:
            path = prefix / "share" / package / kind / f"{name}{suffix}"
            if path.is_file():
                return path
        raise UnknownMessageType(f"no {package}/{kind}/{name}{suffix} under share/ of {[str(p) for p in self._prefixes]}")

    def text(self, msgtype: str) -> str:
        """The .msg file of one type, as installed."""
        return self._file(msgtype, ".msg").read_text()

    def type_hash(self, msgtype: str) -> str:
        """RIHS01 hash of the type from its installed type description."""
        package, kind, name = split_type(msgtype)
        description = json.loads(self._file(msgtype, ".json").read_text())
        wanted = f"{package}/{kind}/{name}"
        for entry in description.get("type_hashes", []):
            if entry.get("type_name") == wanted:
                return entry["hash_string"]
        raise UnknownMessageType(f"{self._file(msgtype, '.json')} has no hash for {wanted}")

    def _definition(self, msgtype: str) -> str:
        seen: set[str] = set()

        def append(name: str, depth: int) -> str:
            if depth <= 0:
                raise UnknownMessageType(f"{msgtype}: message definitions nest too deeply (a cycle?)")
            text = self.text(name)
            package = split_type(name)[0]
            for dependency in dependencies(text, package):
                if dependency not in seen:
                    seen.add(dependency)
                    text += "\n" + SEPARATOR + f"MSG: {dependency}\n" + append(dependency, depth - 1)
            return text

        return append(msgtype, 50)


def dependencies(text: str, package: str) -> list[str]:
    """Non-primitive field types of a .msg text as "pkg/Name", sorted (rosbag2 keeps a std::set)."""
    found = set()
    for match in _FIELD_TYPE.finditer(text):
        token = match.group(1)
        if token in _PRIMITIVES:
            continue
        found.add(token if "/" in token else f"{package}/{token}")
    return sorted(found)
