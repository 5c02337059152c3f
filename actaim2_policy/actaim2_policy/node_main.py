"""main() of the bag nodes: they must finish their work (close the bag, print the summary) on
Ctrl-C and SIGTERM instead of being torn down mid-write.

rclpy's own signal handler would shut the context down at once; here SIGINT and SIGTERM only set
``stop``, the spin loop sees it within ``SPIN_POLL`` and calls ``node.finish()``. A node may also
end its run itself by setting ``node.done`` (end of replay, write error). ``finish()`` returns the
process exit code. A node whose parameters are unusable raises ValueError or OSError from its
constructor: one error line and exit code 1, no traceback.
"""
from __future__ import annotations

import signal
import threading
from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from actaim2.runtime import apply_ros_defaults

SPIN_POLL = 0.1  # s: the longest the loop waits before it looks at its flags again


def run(make_node: Callable[[threading.Event], Node], name: str, args: list[str] | None = None) -> int:
    """``make_node(stop)`` builds a Node that also has ``done`` (an Event) and ``finish() -> int``."""
    apply_ros_defaults()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    try:
        node = make_node(stop)
    except (OSError, ValueError) as exc:
        rclpy.logging.get_logger(name).error(f"cannot start: {exc}")
        rclpy.try_shutdown()
        return 1
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    code = 1
    try:
        while not stop.is_set() and not node.done.is_set() and executor.context.ok():
            executor.spin_once(timeout_sec=SPIN_POLL)
    except ExternalShutdownException:
        pass
    finally:
        stop.set()
        code = node.finish()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return code
