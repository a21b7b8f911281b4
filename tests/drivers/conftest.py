"""Fixtures for the driver tests: a thread-leak guard and small synthetic streams with truth."""

from __future__ import annotations

import pytest

from drivers.emulators.sources import synthetic_stream


@pytest.fixture(autouse=True)
def _thread_guard(no_leaked_threads):
    """Every driver test fails if it leaves a thread running (guard in tests/conftest.py)."""
    yield


@pytest.fixture(scope="session")
def stream_blocks(breaker):
    """About 0.2 s of stream: idle, an opening, idle — in 4096-sample blocks."""
    return list(synthetic_stream(breaker, operations=("open",), idle_s=0.03, seed=3))
