"""Long commands' progress: a tqdm bar with rate and ETA on a terminal, whole lines with the same
figures in a log (a file or a pipe), never carriage-return redraws there."""
from __future__ import annotations

import io

from actaim2.progress import PlainProgress, progress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_plain_lines_with_count_rate_and_eta():
    log = io.StringIO()
    bar = progress(total=4, desc="collect", unit="traj", stream=log, interval=0.0)
    assert isinstance(bar, PlainProgress)
    for _ in range(3):
        bar.update(1)
    bar.set_postfix(stored=3)
    bar.write("an error line")
    bar.close()
    bar.close()  # once only
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert lines[0].startswith("collect: 1/4 traj (") and "traj/s, ETA " in lines[0]
    assert lines[2].startswith("collect: 3/4 traj") and lines[3] == "an error line"
    assert lines[4].startswith("collect: 3/4 traj (") and "done in 0:00) stored=3" in lines[4]
    assert len(lines) == 5


def test_plain_lines_are_spaced_by_the_interval_and_iteration_counts():
    log = io.StringIO()
    assert list(progress(range(5), desc="views", unit="sample", stream=log, interval=3600.0)) == \
        list(range(5))
    assert len(log.getvalue().splitlines()) == 1  # only the final line
    assert log.getvalue().startswith("views: 5/5 sample (")


def test_a_terminal_gets_a_tqdm_bar_with_rate_and_eta():
    screen = Terminal()
    bar = progress(total=10, desc="train", unit="step", stream=screen)
    assert not isinstance(bar, PlainProgress)
    for _ in range(10):
        bar.update(1)
    bar.close()
    out = screen.getvalue()
    assert "train: 100%" in out and "10/10" in out and "step/s]" in out and "<00:00" in out
    assert progress(total=3, stream=io.StringIO(), disable=True).disable
