"""One torch thread for the training tests, as in tests/models/conftest.py: the networks are small,
and on a shared 2-core machine a second spinning OpenMP thread made training steps 4x slower."""
from __future__ import annotations

from typing import Iterator

import pytest
import torch


@pytest.fixture(autouse=True)
def one_torch_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
