"""The main() of every ROS node executable: one function per way a node runs.

* :func:`spin`: a server node that only answers callbacks. rclpy's own signal handler ends it:
  Ctrl-C shuts the context down at once, which is all such a node needs.
* :func:`spin_until`: a node with work to finish on Ctrl-C / SIGTERM (close a bag, abort and
  answer running action goals). The signals only set ``stop``; the main thread spins in steps of
  at most :data:`SPIN_POLL` (Python runs signal handlers only between the executor's waits), and
  once ``stop`` is set calls the node's ``finish()`` while the context is still up.
* :func:`run_client`: a client whose work runs in the main thread (episodes, a keyboard loop, a
  benchmark) while an executor spins the node's callbacks in a thread. By default the signals
  only set ``stop`` too, so the client can cancel its running goal before the context goes.

Each applies the project's ROS defaults before ``rclpy.init()``, has the process write every
thread's Python stack to stderr (the node's log) on :data:`STACK_DUMP_SIGNAL` (``actaim2 launch``
sends it to a node that does not stop after SIGINT, before killing it: the log then says where it
hung), turns a constructor's ValueError or OSError (unusable parameters, an unreadable file) into
one ``cannot start: <why>`` line and exit code 1 instead of a traceback, and shuts down in the one
safe order: spinning stopped (a client's spin thread joined: out of rcl, no callback running; a
thread left inside rcl aborted the process at exit), executor, node, context.

"""
from __future__ import annotations

import faulthandler
import signal
import threading
from typing import Callable, TypeVar

import rclpy
from rclpy.executors import (
    Executor,
    ExternalShutdownException,
    MultiThreadedExecutor,
    SingleThreadedExecutor,
)
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from actaim2.runtime import STACK_DUMP_SIGNAL, apply_ros_defaults

SHUTDOWN_SIGNALS = (signal.SIGINT, signal.SIGTERM)
SPIN_POLL = 0.1  # wall seconds: the longest a spin loop waits before it looks at its flag or deadline again


N = TypeVar("N", bound=Node)


def spin(make_node: Callable[[], Node], name: str, args: list[str] | None = None, threads: int = 1) -> int:
    """Run ``make_node()`` with ``threads`` executor threads until Ctrl-C or until the node shuts
    its context down itself (``self.context.try_shutdown()``). Exit code 0, or 1 if it cannot start."""

    _init(args)
    try:
        node = _start(make_node, name)
    except KeyboardInterrupt:  # Ctrl-C while the node was being built: the same end, without a traceback
        rclpy.try_shutdown()
        return 0
    if node is None:
        return 1
    executor = _executor(threads)
    try:
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # Ctrl-C shuts the context down from rclpy's signal handler; a subscription taken in the
        # same instant raises RuntimeError from rcl. That is the normal end, anything else is not.
        if rclpy.ok():
            raise
    finally:
        _close(executor, node)
    return 0


def spin_until(make_node: Callable[[threading.Event], Node], name: str, args: list[str] | None = None,
               threads: int = 1) -> int:
    """Spin ``make_node(stop)`` until ``stop`` is set (SIGINT, SIGTERM, or the node itself ending
    its run: end of replay, a write error) or the context ends; then return ``node.finish()`` (the
    node's last work, returning the exit code), called while the context is up and the node's
    executor (``node.executor``) can still spin. A signal during start-up is acted on as soon as
    the node is up."""
    stop = _init_stoppable(args)
    node = _start(lambda: make_node(stop), name)
    if node is None:
        return 1
    executor = _executor(threads)
    executor.add_node(node)
    try:
        while not stop.is_set() and executor.context.ok():
            executor.spin_once(timeout_sec=SPIN_POLL)
    except ExternalShutdownException:
        pass
    finally:
        stop.set()
        try:
            code = node.finish()
        finally:
            _close(executor, node)
    return code


def run_client(make_node: Callable[[threading.Event], N], body: Callable[[N, threading.Event], int], name: str,
               args: list[str] | None = None, own_signals: bool = True) -> int:
    """Return ``body(node, stop)`` for ``node = make_node(stop)``, run in the main thread while a
    single-threaded executor spins the node in another (the waiting is the body's; the callbacks only
    keep messages and complete futures). ``own_signals``: SIGINT and SIGTERM only set ``stop`` (the
    body cancels what runs and ends); False keeps rclpy's handler (Ctrl-C shuts the context down at
    once), for a client with nothing to cancel."""
    if own_signals:
        stop = _init_stoppable(args)
    else:
        _init(args)
        stop = threading.Event()
    node = _start(lambda: make_node(stop), name)
    if node is None:
        return 1
    spinner = BackgroundSpinner(node)
    try:
        return body(node, stop)
    finally:
        spinner.stop()
        _close(spinner.executor, node)


class BackgroundSpinner:
    """A single-threaded executor spinning ``nodes`` in a background thread, one callback at a time,
    until :meth:`stop` (or the context's end). Once ``stop`` returns no callback is running, so the
    executor can be shut down and the nodes destroyed: rclpy 7.1's ``Executor.shutdown`` does not wait
    for a running callback and destroys the guard condition it triggers on its way out (a traceback
    from the spin thread, or a task's "exception was never retrieved")."""

    def __init__(self, *nodes: Node) -> None:
        self.executor = SingleThreadedExecutor()
        for node in nodes:
            self.executor.add_node(node)
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            while not self._done.is_set() and self.executor.context.ok():
                self.executor.spin_once(timeout_sec=SPIN_POLL)
        except ExternalShutdownException:  # Ctrl-C under rclpy's own handler (run_client's own_signals=False)
            pass

    def stop(self) -> None:
        """End the spinning and wait for the thread (the executor stays up: shut it down next)."""
        self._done.set()
        self._thread.join()


def _init(args: list[str] | None, signal_handler_options: SignalHandlerOptions | None = None) -> None:
    """The project's ROS defaults, the stack dump on :data:`STACK_DUMP_SIGNAL`, then ``rclpy.init``
    (None: with rclpy's own SIGINT and SIGTERM handlers)."""
    apply_ros_defaults()
    faulthandler.register(STACK_DUMP_SIGNAL, all_threads=True)
    rclpy.init(args=args, signal_handler_options=signal_handler_options)


def _init_stoppable(args: list[str] | None) -> threading.Event:
    """rclpy without its signal handler, and an event that SIGINT and SIGTERM set instead: rclpy's
    handler would shut the context down before running goals could be cancelled or answered, and a
    KeyboardInterrupt raised wherever the main thread is (inside the executor's own code, inside
    SAPIEN's start-up) left the executor unable to spin or crashed the process at exit."""
    _init(args, SignalHandlerOptions.NO)
    stop = threading.Event()
    for signum in SHUTDOWN_SIGNALS:
        signal.signal(signum, lambda *_: stop.set())
    return stop


def _start(make_node: Callable[[], N], name: str) -> N | None:
    """The node, or None after one error line (and the context shut down) if it cannot start."""
    try:
        return make_node()
    except (OSError, ValueError) as exc:
        rclpy.logging.get_logger(name).error(f"cannot start: {exc}")
        rclpy.try_shutdown()
        return None


def _executor(threads: int) -> Executor:
    return SingleThreadedExecutor() if threads == 1 else MultiThreadedExecutor(num_threads=threads)


def _close(executor: Executor, node: Node) -> None:
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown()
