"""Fixtures for the driver tests: a thread-leak guard and small synthetic streams with truth."""

from __future__ import annotations

import threading
import time

import pytest

from drivers.emulators.sources import synthetic_stream


@pytest.fixture(autouse=True)
def no_leaked_threads():
    """Fail a test that leaves a thread running (reader threads, emulator writers)."""
    before = set(threading.enumerate())
    yield
    deadline = time.monotonic() + 2.0
    while True:
        leaked = [t for t in threading.enumerate() if t not in before and t.is_alive()]
        if not leaked or time.monotonic() > deadline:
            break
        time.sleep(0.01)
    assert not leaked, f"test leaked threads: {[t.name for t in leaked]}"


@pytest.fixture(scope="session")
def stream_blocks(breaker):
    """About 0.2 s of stream: idle, an opening, idle — in 4096-sample blocks."""
    return list(synthetic_stream(breaker, operations=("open",), idle_s=0.03, seed=3))
