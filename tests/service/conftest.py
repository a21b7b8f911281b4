"""Service test fixtures: a real database per test (SQLite always; PostgreSQL when
HVCB_TEST_POSTGRES_URL is set and answers), migrated by Alembic, and an app built by the factory."""

from __future__ import annotations

import contextlib
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from service.settings import load_settings
from service.storage import crud
from service.storage.db import make_engine, upgrade
from service.storage.scratch import scratch_pg_database, unreachable

PG_URL = os.environ.get("HVCB_TEST_POSTGRES_URL")
REDIS_URL = os.environ.get("HVCB_TEST_REDIS_URL")
BREAKER_FILE = Path(__file__).resolve().parents[2] / "config" / "breakers" / "reference-252kV.toml"


def _reachable(url: str, default_port: int) -> str | None:
    return unreachable(url, default_port)


@pytest.fixture(scope="session")
def pg_server():
    """A fresh PostgreSQL database for this test session, dropped at the end."""
    if not PG_URL:
        pytest.skip("PostgreSQL lane off: HVCB_TEST_POSTGRES_URL is empty (unset, it is 127.0.0.1:5432/test)")
    why = _reachable(PG_URL, 5432)
    if why:
        pytest.skip(f"PostgreSQL lane off: {why}")
    with scratch_pg_database(PG_URL, "hvcb_test") as url:
        yield url


def _fresh_pg_schema(url: str) -> None:
    from sqlalchemy import text

    eng = make_engine(url)
    with eng.begin() as conn:
        conn.execute(text("DROP SCHEMA public CASCADE"))
        conn.execute(text("CREATE SCHEMA public"))
    eng.dispose()


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def db_url(request, tmp_path):
    """A migrated, empty database URL of each kind."""
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    else:
        url = request.getfixturevalue("pg_server")
        _fresh_pg_schema(url)
    (tmp_path / "data").mkdir(exist_ok=True)
    upgrade(url)
    return url


def make_settings(tmp_path, db_url, **kw):
    kw.setdefault("executor", "inline")
    # the route matrices send many wrong keys from one test client; throttling (D7) has its own
    # tests in tests/security/test_d07_throttle.py
    kw.setdefault("server", {"auth_free_failures": 100_000})
    return load_settings(data_dir=tmp_path / "data", database_url=db_url, broker_url="",
                         bootstrap_admin_key=None, **kw)


class Env:
    """A running app with a key per role."""

    def __init__(self, app, client, keys, settings):
        self.app, self.client, self.keys, self.settings = app, client, keys, settings

    def h(self, role="admin"):
        return {"X-API-Key": self.keys[role]}

    @property
    def Session(self):
        return self.app.state.Session

    def wait_fits(self, n=None, timeout=60.0):
        """Wait until no fit is queued/running (and at least n exist)."""
        from sqlalchemy import func, select

        from service.storage.models import FitRow

        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.Session() as s:
                pending = crud.queue_depth(s)
                total = s.scalar(select(func.count()).select_from(FitRow))
            if pending == 0 and (n is None or total >= n):
                return
            time.sleep(0.05)
        raise AssertionError(f"fits still pending after {timeout} s")


@contextlib.contextmanager
def running_app(settings):
    """``(app, client, keys)``: the app started under a TestClient, with a key per role."""
    from fastapi.testclient import TestClient

    from service.api.app import create_app

    shown = []
    app = create_app(settings, on_key=shown.append)
    with TestClient(app) as client:
        keys = {"admin": shown[0]}
        with app.state.Session() as s, s.begin():
            for role in ("reader", "operator"):
                keys[role] = crud.create_api_key(s, name=f"test-{role}", role=role)[1]
        yield app, client, keys


@pytest.fixture
def env(tmp_path, db_url):
    settings = make_settings(tmp_path, db_url)
    with running_app(settings) as (app, client, keys):
        yield Env(app, client, keys, settings)


@pytest.fixture(scope="session")
def breaker():
    from service.breaker_file import load_breaker

    return load_breaker(BREAKER_FILE)


def synth(breaker, kind="open", seed=0, scale=None, start_time=None):
    from drivers.synthetic import synthesize_capture

    p = dict(breaker.design_parameters())
    for k, v in (scale or {}).items():
        p[k] *= v
    cap, _ = synthesize_capture(breaker, kind, p, rng=np.random.default_rng(seed))
    if start_time is not None:
        cap = type(cap)(**{**cap.__dict__, "start_time": start_time})
    return cap


@pytest.fixture(autouse=True)
def no_leaked_threads():
    before = {t.ident for t in threading.enumerate()}
    yield
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        leaked = [t for t in threading.enumerate() if t.ident not in before and t.is_alive()
                  and not t.name.startswith(("QueueFeederThread", "ThreadPoolExecutor", "asyncio"))]
        if not leaked:
            return
        time.sleep(0.05)
    raise AssertionError(f"threads leaked: {[t.name for t in leaked]}")
