"""The policy tests' checkpoint: trained once per test session (tiny_policy.py), on one torch thread
(a second spinning OpenMP thread slows small networks down on a shared 2-core machine)."""
from __future__ import annotations

import pytest
import torch

from tiny_policy import TinyCheckpoint, make_checkpoint


@pytest.fixture(scope="session")
def tiny_checkpoint(tmp_path_factory) -> TinyCheckpoint:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return make_checkpoint(tmp_path_factory.mktemp("tiny_policy"))
    finally:
        torch.set_num_threads(threads)
