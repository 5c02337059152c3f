"""Run independent tasks on worker processes or a Ray cluster; results come back as they finish.

A worker is an object built once per process from a picklable setup (``make(setup)``, a
module-level function) with a ``run(task) -> result`` method; it keeps its expensive state (a
simulator, loaded models) across tasks. Three executors, one interface (:func:`run_unordered`):

* ``workers=0`` - in this process (debugging, tests);
* ``workers=N`` - N spawned processes (``concurrent.futures``), a few tasks in flight per worker
  so memory stays flat however many tasks there are; a worker that dies stops the run with
  BrokenProcessPool instead of hanging it, and a parent that dies without cleaning up (SIGTERM,
  SIGKILL) takes its workers with it within :data:`ORPHAN_POLL_S` (they would otherwise go on
  simulating the tasks already queued to them, then wait forever);
* ``ray_address`` - N Ray actors on a cluster (``"auto"``, ``"ray://host:10001"``, or
  ``"local"`` to start a private local instance, pinned to 127.0.0.1 like the project's DDS).
  Ray is an optional extra (``pip install -e src/actaim2[ray]``); without it this executor says so.

Results arrive in completion order (:func:`run_unordered`): callers key them by task (e.g. append
to a JSONL). :func:`run_ordered` restores the task order on top, for a writer whose output must
not depend on the worker count (collection's dataset index).
"""
from __future__ import annotations

import atexit
import gc
import importlib.util
import multiprocessing as mp
import os
import threading
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from types import ModuleType
from typing import Any, Callable, Iterable, Iterator

IN_FLIGHT_PER_WORKER = 2
ORPHAN_POLL_S = 1.0
LOOPBACK = "127.0.0.1"
# On Linux, Ray swaps a loopback node address for the machine's interface address (so that other
# nodes could join) unless "clusters" are off, which Ray reads from this variable once, on import.
RAY_CLUSTER_VAR = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"

_WORKER: Any = None


def _exit_when_orphaned(parent: int) -> None:
    """Poll the parent pid; once the worker is re-parented (its parent died), exit at once.

    Polling getppid is POSIX-portable, unlike Linux's PR_SET_PDEATHSIG, and costs nothing.
    """
    while os.getppid() == parent:
        time.sleep(ORPHAN_POLL_S)
    os._exit(1)


def _init(make: Callable[[Any], Any], setup: Any, parent: int) -> None:
    global _WORKER
    threading.Thread(target=_exit_when_orphaned, args=(parent,), name="orphan-watch", daemon=True).start()
    _WORKER = make(setup)
    atexit.register(_release)


def _release() -> None:
    """Free the worker while the interpreter is still whole. A spawned worker ends with sys.exit,
    and objects of nanobind extensions (Ruckig's, inside a planner) that outlive their module's
    teardown make nanobind print a leak report of ~100 lines per worker at the end of every run."""
    global _WORKER
    _WORKER = None
    gc.collect()


def _run(task: Any) -> Any:
    return _WORKER.run(task)


def run_unordered(make: Callable[[Any], Any], setup: Any, tasks: Iterable[Any], workers: int = 2,
                  ray_address: str | None = None) -> Iterator[Any]:
    """Results of ``make(setup).run(task)`` for every task, in completion order."""
    if ray_address:
        yield from _ray(make, setup, tasks, max(1, workers), ray_address)
    elif workers == 0:
        worker = make(setup)
        yield from map(worker.run, tasks)
    else:
        yield from _processes(make, setup, tasks, workers)


class _Numbered:
    """A worker whose results carry their task's position, so that :func:`run_ordered` can restore it."""

    def __init__(self, worker: Any):
        self.worker = worker

    def run(self, numbered: tuple[int, Any]) -> tuple[int, Any]:
        position, task = numbered
        return position, self.worker.run(task)


def _numbered(setup: tuple[Callable[[Any], Any], Any]) -> _Numbered:
    make, inner = setup
    return _Numbered(make(inner))


def run_ordered(make: Callable[[Any], Any], setup: Any, tasks: Iterable[Any], workers: int = 2,
                ray_address: str | None = None) -> Iterator[Any]:
    """Results of ``make(setup).run(task)`` for every task, in task order.

    Executed as :func:`run_unordered` executes them; a result that finishes before those of
    earlier tasks waits here until they come, so it costs memory only while a slow task holds
    the ones after it (a few, with tasks of similar length)."""
    waiting: dict[int, Any] = {}
    following = 0
    for position, result in run_unordered(_numbered, (make, setup), enumerate(tasks), workers, ray_address):
        waiting[position] = result
        while following in waiting:
            yield waiting.pop(following)
            following += 1


def _processes(make, setup, tasks: Iterable[Any], workers: int) -> Iterator[Any]:
    os.environ.setdefault("OMP_NUM_THREADS", "1")  # inherited by the workers (Open3D, PyTorch)
    pool = ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"), initializer=_init,
                               initargs=(make, setup, os.getpid()))
    todo = iter(tasks)
    pending: set[Future] = set()
    try:
        for task in todo:
            pending.add(pool.submit(_run, task))
            if len(pending) >= IN_FLIGHT_PER_WORKER * workers:
                break
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                following = next(todo, None)
                if following is not None:
                    pending.add(pool.submit(_run, following))
                yield future.result()
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


def ray_available() -> str | None:
    """None when Ray is installed, else why not. Looks without importing: importing Ray fixes
    its settings (see :data:`RAY_CLUSTER_VAR`) before a local instance could pin them."""
    if importlib.util.find_spec("ray") is None:
        return "Ray is not installed: pip install -e src/actaim2[ray]"
    return None


def _start_local_ray(ray: ModuleType, workers: int) -> str:
    """A private Ray instance whose processes use and listen on loopback only, and its GCS address;
    RuntimeError when Ray was imported in this process before its cluster setting was turned off."""
    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, _node_ip_address=LOOPBACK)
    address = ray.get_runtime_context().gcs_address
    if not address.startswith(f"{LOOPBACK}:"):
        ray.shutdown()
        raise RuntimeError(f"the local Ray instance came up on {address}, not loopback: set {RAY_CLUSTER_VAR}=0 "
                           "before anything imports ray")
    return address


def _ray(make, setup, tasks: Iterable[Any], workers: int, address: str) -> Iterator[Any]:
    problem = ray_available()
    if problem:
        raise RuntimeError(problem)
    if address == "local":
        os.environ.setdefault(RAY_CLUSTER_VAR, "0")  # before the import below
    import ray
    from ray.util import ActorPool

    started_here = not ray.is_initialized()
    if started_here:
        if address == "local":
            print(f"Ray: a local instance at {_start_local_ray(ray, workers)} (loopback only)", flush=True)
        else:
            ray.init(address=address, log_to_driver=False)

    @ray.remote(num_cpus=1)
    class _Actor:
        def __init__(self, make_, setup_):
            os.environ.setdefault("OMP_NUM_THREADS", "1")
            self.worker = make_(setup_)

        def run(self, task):
            return self.worker.run(task)

    actors = [_Actor.remote(make, setup) for _ in range(workers)]
    try:
        yield from ActorPool(actors).map_unordered(lambda actor, task: actor.run.remote(task), tasks)
    finally:
        for actor in actors:
            ray.kill(actor)
        if started_here:
            ray.shutdown()
