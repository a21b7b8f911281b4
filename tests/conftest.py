"""Fixtures every test may use, the lanes' default addresses, and the run's one-line-per-lane summary.

A lane is a group of tests that needs a service: PostgreSQL, Redis (Celery), Chromium, the shared
data folder, the IEC 61850 library. Each runs whenever its service answers at its default address
(below) and skips with the reason otherwise. Set ``HVCB_TEST_POSTGRES_URL`` or
``HVCB_TEST_REDIS_URL`` to another address, or to an empty string to turn that lane off.
"""

import os
import threading
import time
from collections import Counter, defaultdict
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BREAKER_FILE = REPO / "config" / "breakers" / "reference-252kV.toml"

# The services' default addresses (PostgreSQL's and Redis's own defaults; the database `test`
# is only the maintenance connection: each session creates and drops scratch databases beside it).
os.environ.setdefault("HVCB_TEST_POSTGRES_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test")
os.environ.setdefault("HVCB_TEST_REDIS_URL", "redis://127.0.0.1:6379/0")


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


# -- the lanes' summary --------------------------------------------------------------------------
def _lanes_of(item) -> list[str]:
    """The lanes a test belongs to: by its markers and fixtures; the shared-data lane by its module
    reading ``shared_dir()`` or the ``samples_dir`` fixture."""
    names = set(getattr(item, "fixturenames", ()))
    lanes = []
    if item.get_closest_marker("postgres") or names & {"pg_server", "pg_database"}:
        lanes.append("PostgreSQL")
    if item.get_closest_marker("redis"):
        lanes.append("Celery/Redis")
    if "browser" in names:
        lanes.append("browser (Chromium)")
    if "promtool" in names:
        lanes.append("Prometheus rules (promtool)")
    if "iec61850" in str(item.path):
        lanes.append("IEC 61850")
    if "samples_dir" in names or _reads_shared(item.path):
        lanes.append("shared data (../shared)")
    return lanes


_SHARED_READERS: dict[Path, bool] = {}


def _reads_shared(path: Path) -> bool:
    if path not in _SHARED_READERS:
        _SHARED_READERS[path] = "shared_dir()" in path.read_text(encoding="utf-8", errors="replace")
    return _SHARED_READERS[path]


_ITEM_LANES: dict[str, list[str]] = {}
_RAN: Counter = Counter()
_SKIPPED: dict[str, Counter] = defaultdict(Counter)


# End-to-end runs of whole processes, outages, protocols and studies, 10–150 s each (the slowest
# of `--durations`): `make test` runs them, `make check` (the inner loop) leaves them out. Each
# module's own unit tests of the same code run in `make check` too.
INTEGRATION_MODULES = frozenset({
    "tests/service/test_schemathesis.py", "tests/service/test_agent.py", "tests/service/test_outage.py",
    "tests/service/test_notifications_demo.py", "tests/service/test_generated_client.py",
    "tests/service/test_breaker_diagnoses_api.py", "tests/service/test_diagnosis_api.py",
    "tests/service/test_ctrl_c.py", "tests/service/test_fleet_daqs.py", "tests/service/test_demo.py",
    "tests/refit/test_refit_interrupt.py", "tests/storage/test_retention.py", "tests/storage/test_backup.py",
    "tests/storage/test_migration_upgrade.py", "tests/conditions/test_classify_study.py",
    "tests/security/test_d01_pool.py",
})


def pytest_collection_modifyitems(items):
    for item in items:
        if Path(item.path).resolve().relative_to(REPO).as_posix() in INTEGRATION_MODULES:
            item.add_marker(pytest.mark.integration)
        _ITEM_LANES[item.nodeid] = lanes = _lanes_of(item)
        # Under pytest-xdist the workers collect and the controller reports: the lanes travel
        # with each report as a user property.
        item.user_properties.append(("lanes", lanes))


def pytest_runtest_logreport(report):
    lanes = _ITEM_LANES.get(report.nodeid) or dict(report.user_properties).get("lanes") or []
    if hasattr(report, "wasxfail"):  # an expected failure ran: pytest reports it as skipped
        if report.when == "call":
            for lane in lanes or ["core (SQLite, in-process)"]:
                _RAN[lane] += 1
        return
    if report.skipped:
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        reason = reason.removeprefix("Skipped: ")
        _SKIPPED[lanes[0] if lanes else "other"][reason] += 1
    elif report.when == "call":
        for lane in lanes or ["core (SQLite, in-process)"]:
            _RAN[lane] += 1


def pytest_terminal_summary(terminalreporter):
    """One summary at the end of the run: each lane with the tests it ran, and what skipped, why."""
    if not (_RAN or _SKIPPED):
        return
    w = terminalreporter
    w.section("lanes")
    for lane, n in sorted(_RAN.items()):
        w.line(f"ran      {lane}: {n} test(s)")
    for lane, reasons in sorted(_SKIPPED.items()):
        for reason, n in reasons.most_common():
            w.line(f"skipped  {lane}: {n} test(s): {reason}")
    if not _SKIPPED:
        w.line("skipped  none")
