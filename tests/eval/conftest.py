"""One torch thread in the evaluation tests' own process (tiny checkpoints are trained here): on a
shared 2-core machine a second spinning OpenMP thread only slows small networks down."""
from __future__ import annotations

from typing import Iterator

import pytest
import torch


@pytest.fixture(autouse=True, scope="session")
def one_torch_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
