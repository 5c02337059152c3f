"""actaim2.parallel's process executor: results of every task (in task order when asked), and no worker
outlives a killed parent."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from actaim2.parallel import ORPHAN_POLL_S, run_ordered, run_unordered

# A parent whose workers record their pid, then each sit on a long task.
PARENT = textwrap.dedent("""
    import os, sys, time
    from pathlib import Path
    from actaim2.parallel import run_unordered

    class Sleeper:
        def __init__(self, folder):
            (Path(folder) / str(os.getpid())).touch()

        def run(self, task):
            time.sleep(600)

    def make(folder):
        return Sleeper(folder)

    if __name__ == "__main__":
        for _ in run_unordered(make, sys.argv[1], range(8), workers=2):
            pass
""")


class Square:
    def run(self, task: int) -> int:
        return task * task


def make_square(_setup: None) -> Square:
    return Square()


class SlowFirst:
    """Task 0 takes seconds, the others none: with two workers, the rest finish before it."""

    def run(self, task: int) -> int:
        time.sleep(3.0 if task == 0 else 0.0)
        return task


def make_slow_first(_setup: None) -> SlowFirst:
    return SlowFirst()


def _alive(pid: int) -> bool:
    """Running, not merely a zombie waiting for whoever adopted it to reap it."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except FileNotFoundError:
        return False
    return state != "Z"


@pytest.mark.parametrize("workers", [0, 2])
def test_every_task_comes_back(workers: int) -> None:
    assert sorted(run_unordered(make_square, None, range(7), workers=workers)) == [t * t for t in range(7)]


@pytest.mark.timeout(120)
def test_ordered_results_come_in_task_order_when_they_finish_out_of_it() -> None:
    assert next(run_unordered(make_slow_first, None, range(6), workers=2)) != 0  # the case run_ordered is for
    assert list(run_ordered(make_slow_first, None, range(6), workers=2)) == list(range(6))
    assert list(run_ordered(make_square, None, range(5), workers=0)) == [t * t for t in range(5)]


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads process states from /proc")
@pytest.mark.timeout(120)
def test_workers_exit_when_their_parent_is_killed(tmp_path) -> None:
    script = tmp_path / "parent.py"
    script.write_text(PARENT)
    pids = tmp_path / "pids"
    pids.mkdir()
    parent = subprocess.Popen([sys.executable, str(script), str(pids)], env=dict(os.environ))
    try:
        deadline = time.monotonic() + 60
        while len(list(pids.iterdir())) < 2 and time.monotonic() < deadline:
            time.sleep(0.2)
        workers = [int(p.name) for p in pids.iterdir()]
        assert len(workers) == 2, f"workers started: {workers}"
        time.sleep(0.5)  # the watch thread is started before the worker object is built: it is running now
        assert all(_alive(pid) for pid in workers)
        parent.send_signal(signal.SIGKILL)
        parent.wait(10)
        deadline = time.monotonic() + 10 * ORPHAN_POLL_S
        while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = [pid for pid in workers if _alive(pid)]
        assert not left, f"workers still running {10 * ORPHAN_POLL_S:.0f} s after their parent was killed: {left}"
    finally:
        parent.kill()
        for pid in (int(p.name) for p in pids.iterdir()):
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


# A parent whose workers each hold a Ruckig trajectory generator (a nanobind object), as an
# evaluation worker's planner does.
RUCKIG_PARENT = textwrap.dedent("""
    import ruckig
    from actaim2.parallel import run_unordered

    class Holder:
        def __init__(self, dofs):
            self.generator = ruckig.Ruckig(dofs, 0.01)

        def run(self, task):
            return task

    def make(dofs):
        return Holder(dofs)

    if __name__ == "__main__":
        print(sorted(run_unordered(make, 7, range(4), workers=2)))
""")


@pytest.mark.timeout(120)
def test_workers_free_their_state_before_exit_so_nanobind_reports_no_leak(tmp_path) -> None:
    script = tmp_path / "parent.py"
    script.write_text(RUCKIG_PARENT)
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=100, env=dict(os.environ))
    assert run.returncode == 0 and run.stdout.strip() == "[0, 1, 2, 3]", run.stdout + run.stderr
    assert "leaked" not in run.stderr, run.stderr
