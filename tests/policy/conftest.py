"""The policy tests' checkpoint: trained once per test session (tiny_policy.py), on one torch thread
(a second spinning OpenMP thread slows small networks down on a shared 2-core machine)."""
from __future__ import annotations

import pytest

from tiny_policy import TinyCheckpoint, make_checkpoint
from torch_threads import single_torch_thread


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory) -> TinyCheckpoint:
    with single_torch_thread():
        return make_checkpoint(tmp_path_factory.mktemp("tiny_policy"))
