"""The browser the viewer tests drive: a missing Chromium skips them on a developer's machine and
fails them under CI (``CI=true``), where scripts/setup.sh has installed it."""
from __future__ import annotations

import os

import pytest

from browser import chromium


@pytest.fixture
def browser() -> str:
    binary = chromium()
    if binary is None:
        message = "chromium is not installed (bash scripts/setup.sh installs Debian's chromium)"
        if os.environ.get("CI") == "true":
            pytest.fail(f"{message}: the browser test may not be skipped under CI")
        pytest.skip(message)
    return binary
