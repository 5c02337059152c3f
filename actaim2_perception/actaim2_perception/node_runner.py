"""The main() of every node in this package: ROS defaults, init, spin, clean Ctrl-C shutdown.

A node whose configuration is unusable (unreadable calibration file, unknown robot) raises
ValueError or OSError from its constructor; that becomes one clear error line and exit code 1
instead of a traceback. A node ends its own run with ``self.context.try_shutdown()``.
"""
from __future__ import annotations

from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from actaim2.runtime import apply_ros_defaults


def run(make_node: Callable[[], Node], name: str, args: list[str] | None = None) -> int:
    apply_ros_defaults()
    rclpy.init(args=args)
    try:
        node = make_node()
    except (OSError, ValueError) as exc:
        rclpy.logging.get_logger(name).error(f"cannot start: {exc}")
        rclpy.try_shutdown()
        return 1
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # Ctrl-C shuts the context down from rclpy's signal handler; a subscription taken in the
        # same instant raises RuntimeError from rcl. That is the normal end, anything else is not.
        if rclpy.ok():
            raise
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
