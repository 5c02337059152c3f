"""One torch thread for the tests that train or run small networks in the pytest process.

These networks are too small to gain from a second thread, and on a shared 2-core machine a
second spinning OpenMP thread made training steps 4x slower. A folder's conftest imports
:func:`one_torch_thread` (autouse) for all its tests; a longer-lived fixture that trains uses
:func:`single_torch_thread` around its work.
"""
from __future__ import annotations

import contextlib
from typing import Iterator

import pytest
import torch


@contextlib.contextmanager
def single_torch_thread() -> Iterator[None]:
    """torch on one thread inside the block, the previous thread count restored after it."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


@pytest.fixture(autouse=True)
def one_torch_thread() -> Iterator[None]:
    with single_torch_thread():
        yield
