import os
import threading
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BREAKER_FILE = REPO / "config" / "breakers" / "reference-252kV.toml"


def shared_dir() -> Path:
    return Path(os.environ.get("HVCB_SHARED_DIR", REPO.parent / "shared"))


@pytest.fixture(scope="session")
def breaker():
    from service.breaker_file import load_breaker

    return load_breaker(BREAKER_FILE)


@pytest.fixture(scope="session")
def samples_dir():
    d = shared_dir() / "samples"
    if not d.is_dir():
        pytest.skip(f"shared samples not found at {d} (set HVCB_SHARED_DIR)")
    return d


@pytest.fixture
def no_leaked_threads():
    """Fail a test that leaves a thread running (driver reader threads, emulator writers)."""
    before = set(threading.enumerate())
    yield
    deadline = time.monotonic() + 2.0
    while True:
        leaked = [t for t in threading.enumerate() if t not in before and t.is_alive()]
        if not leaked or time.monotonic() > deadline:
            break
        time.sleep(0.01)
    assert not leaked, f"test leaked threads: {[t.name for t in leaked]}"
