"""Two independent views of an interface's RIHS01 type hash, for comparing them in tests.

* ``rosbags_types`` rebuilds, with rosbags, every type rosidl generates from one .msg/.srv/.action
  text: the text is split into its parts the way rosidl_adapter splits it (lines that are exactly
  ``---``), each part is parsed by rosbags' .msg parser, and the implicit types rosidl adds
  (service ``_Event``, the action's ``_SendGoal``/``_GetResult`` services and ``_FeedbackMessage``,
  and the service/action types themselves, described as structs of those) are declared in IDL.
* ``rclpy_type_hash`` reads the hash that the generated type support rclpy loads reports
  (``get_type_hash_func`` of the ``rosidl_{message,service,action}_type_support_t`` behind a
  generated class's ``_TYPE_SUPPORT`` capsule); rmw advertises this hash during discovery.
"""
from __future__ import annotations

import ctypes
import importlib
import os
from pathlib import Path

from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

SEPARATOR = "---"


def split_parts(text: str, kind: str) -> list[str]:
    """The request/response (srv) or goal/result/feedback (action) texts of an interface file.

    rosidl_adapter splits on lines equal to ``---``: one separator for a service, two for an action.
    """
    expected = {"srv": 2, "action": 3}[kind]
    parts: list[list[str]] = [[]]
    for line in text.splitlines():
        if line == SEPARATOR:
            parts.append([])
        else:
            parts[-1].append(line)
    if len(parts) != expected:
        raise ValueError(f"a .{kind} has {expected - 1} '---' separator(s), found {len(parts) - 1}")
    return ["\n".join(lines) + "\n" for lines in parts]


def _parse_part(text: str, package: str, kind: str, name: str) -> dict:
    """rosbags' .msg parser names types <pkg>/msg/<Name>; rosidl puts srv parts under <pkg>/srv/."""
    parsed = get_types_from_msg(text, f"{package}/msg/{name}")
    return {f"{package}/{kind}/{name}": parsed[f"{package}/msg/{name}"]}


def _service_idl(package: str, kind: str, name: str) -> str:
    """Event message and the service type rosidl derives from <name>_Request/<name>_Response."""
    scope = f"{package}::{kind}::{name}"
    return f"""
    struct {name}_Event {{
      service_msgs::msg::ServiceEventInfo info;
      sequence<{scope}_Request, 1> request;
      sequence<{scope}_Response, 1> response;
    }};
    struct {name} {{
      {scope}_Request request_message;
      {scope}_Response response_message;
      {scope}_Event event_message;
    }};"""


def _in_module(package: str, kind: str, body: str) -> str:
    return f"module {package} {{ module {kind} {{ {body} }}; }};"


def rosbags_types(package: str, kind: str, name: str, text: str) -> dict:
    """Every type rosidl generates from ``<package>/<kind>/<name>`` with definition ``text``."""
    if kind == "msg":
        return get_types_from_msg(text, f"{package}/msg/{name}")
    if kind == "srv":
        request, response = split_parts(text, "srv")
        types = _parse_part(request, package, "srv", f"{name}_Request")
        types |= _parse_part(response, package, "srv", f"{name}_Response")
        types |= get_types_from_idl(_in_module(package, "srv", _service_idl(package, "srv", name)))
        return types
    if kind == "action":
        goal, result, feedback = split_parts(text, "action")
        types = _parse_part(goal, package, "action", f"{name}_Goal")
        types |= _parse_part(result, package, "action", f"{name}_Result")
        types |= _parse_part(feedback, package, "action", f"{name}_Feedback")
        scope = f"{package}::action::{name}"
        body = f"""
        struct {name}_SendGoal_Request {{
          unique_identifier_msgs::msg::UUID goal_id;
          {scope}_Goal goal;
        }};
        struct {name}_SendGoal_Response {{
          boolean accepted;
          builtin_interfaces::msg::Time stamp;
        }};
        struct {name}_GetResult_Request {{
          unique_identifier_msgs::msg::UUID goal_id;
        }};
        struct {name}_GetResult_Response {{
          int8 status;
          {scope}_Result result;
        }};
        struct {name}_FeedbackMessage {{
          unique_identifier_msgs::msg::UUID goal_id;
          {scope}_Feedback feedback;
        }};
        {_service_idl(package, "action", f"{name}_SendGoal")}
        {_service_idl(package, "action", f"{name}_GetResult")}
        struct {name} {{
          {scope}_Goal goal;
          {scope}_Result result;
          {scope}_Feedback feedback;
          {scope}_SendGoal send_goal_service;
          {scope}_GetResult get_result_service;
          {scope}_FeedbackMessage feedback_message;
        }};"""
        types |= get_types_from_idl(_in_module(package, "action", body))
        return types
    raise ValueError(f"unknown interface kind {kind!r}")


def interface_files(package_dir: Path) -> list[tuple[str, str, Path]]:
    """(kind, name, path) of every .msg/.srv/.action file of an interface package, sorted."""
    return sorted(
        (path.suffix[1:], path.stem, path)
        for kind in ("msg", "srv", "action")
        for path in (package_dir / kind).glob(f"*.{kind}")
    )


def installed_share_file(package: str, relative: str) -> Path:
    """``<prefix>/share/<package>/<relative>`` of the first prefix on AMENT_PREFIX_PATH that has it."""
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        path = Path(prefix, "share", package, relative)
        if prefix and path.is_file():
            return path
    raise FileNotFoundError(f"share/{package}/{relative} is on no AMENT_PREFIX_PATH prefix")


def jazzy_typestore() -> Typestore:
    """rosbags' ROS 2 Jazzy store, with service_msgs/msg/ServiceEventInfo as rosidl defines it.

    rosbags 0.11.9 keeps ``char[16] client_gid`` of ServiceEventInfo as char, where rosidl maps a
    .msg ``char`` to uint8; its hash of that type (and so of every service ``_Event`` and service
    type) differs from rclpy's. The installed rosidl IDL of the type (its #include lines, which
    rosbags' IDL parser does not take, dropped) replaces the store's definition.
    """
    idl = installed_share_file("service_msgs", "msg/ServiceEventInfo.idl").read_text()
    fixed = get_types_from_idl("\n".join(line for line in idl.splitlines() if not line.startswith("#include")))
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    store = get_typestore(Stores.EMPTY)
    store.register({name: jazzy.fielddefs[name] for name in jazzy.fielddefs.keys() - fixed.keys()} | fixed)
    return store


def jazzy_typestore_with(package: str, package_dir: Path) -> Typestore:
    """:func:`jazzy_typestore` plus every type of the interface package at ``package_dir``."""
    store = jazzy_typestore()
    for kind, name, path in interface_files(package_dir):
        store.register(rosbags_types(package, kind, name, path.read_text()))
    return store


# --- the hash rclpy's generated type support reports ---------------------------------------

class _TypeHash(ctypes.Structure):
    _fields_ = [("version", ctypes.c_uint8), ("value", ctypes.c_uint8 * 32)]


_GetTypeHash = ctypes.CFUNCTYPE(ctypes.POINTER(_TypeHash), ctypes.c_void_p)


class _MessageTypeSupport(ctypes.Structure):  # rosidl_runtime_c/message_type_support_struct.h
    _fields_ = [("typesupport_identifier", ctypes.c_char_p), ("data", ctypes.c_void_p),
                ("func", ctypes.c_void_p), ("get_type_hash_func", _GetTypeHash)]


class _ServiceTypeSupport(ctypes.Structure):  # rosidl_runtime_c/service_type_support_struct.h
    _fields_ = [("typesupport_identifier", ctypes.c_char_p), ("data", ctypes.c_void_p),
                ("func", ctypes.c_void_p), ("request_typesupport", ctypes.c_void_p),
                ("response_typesupport", ctypes.c_void_p), ("event_typesupport", ctypes.c_void_p),
                ("event_message_create_handle_function", ctypes.c_void_p),
                ("event_message_destroy_handle_function", ctypes.c_void_p),
                ("get_type_hash_func", _GetTypeHash)]


class _ActionTypeSupport(ctypes.Structure):  # rosidl_runtime_c/action_type_support_struct.h
    _fields_ = [("goal_service_type_support", ctypes.c_void_p),
                ("result_service_type_support", ctypes.c_void_p),
                ("cancel_service_type_support", ctypes.c_void_p),
                ("feedback_message_type_support", ctypes.c_void_p),
                ("status_message_type_support", ctypes.c_void_p),
                ("get_type_hash_func", _GetTypeHash)]


_capsule_pointer = ctypes.pythonapi.PyCapsule_GetPointer
_capsule_pointer.restype = ctypes.c_void_p
_capsule_pointer.argtypes = [ctypes.py_object, ctypes.c_char_p]


def rclpy_type_hash(cls: type) -> str:
    """``RIHS01_<hex>`` of a generated message, service or action class, as its type support reports."""
    cls.__class__.__import_type_support__()
    if hasattr(cls, "Impl"):
        struct = _ActionTypeSupport
    elif hasattr(cls, "Request"):
        struct = _ServiceTypeSupport
    else:
        struct = _MessageTypeSupport
    address = _capsule_pointer(cls._TYPE_SUPPORT, None)
    type_hash = struct.from_address(address).get_type_hash_func(address).contents
    return f"RIHS{type_hash.version:02d}_{bytes(type_hash.value).hex()}"


def generated_classes(package: str, kind: str, name: str) -> dict[str, type]:
    """Type name -> rclpy generated class, for every type rosidl generates from one interface."""
    cls = getattr(importlib.import_module(f"{package}.{kind}"), name)
    classes = {f"{package}/{kind}/{name}": cls}
    if kind == "srv":
        classes |= {f"{package}/srv/{name}_{part}": getattr(cls, part) for part in ("Request", "Response", "Event")}
    if kind == "action":
        impl = cls.Impl
        classes |= {f"{package}/action/{name}_{part}": getattr(cls, part) for part in ("Goal", "Result", "Feedback")}
        classes[f"{package}/action/{name}_FeedbackMessage"] = impl.FeedbackMessage
        for service_name, service in (("SendGoal", impl.SendGoalService), ("GetResult", impl.GetResultService)):
            classes[f"{package}/action/{name}_{service_name}"] = service
            classes |= {f"{package}/action/{name}_{service_name}_{part}": getattr(service, part)
                        for part in ("Request", "Response", "Event")}
    return classes
