"""No busy database at sign-in (issue 44 item 3): SQLite in WAL, a busy timeout, and a bounded
retry of the unit of work, so a writer holding the lock longer than the busy timeout makes a
sign-in wait, not fail. The writers here are real: a second connection holding SQLite's write
lock from another thread."""

from __future__ import annotations

import re
import sqlite3
import threading

import pytest
from sqlalchemy import text
from sqlalchemy.exc import OperationalError

from service.storage.db import is_locked, make_engine, retry_locked, upgrade


class Writer:
    """Another connection holding SQLite's write lock (BEGIN IMMEDIATE) until released."""

    def __init__(self, path: str):
        self.path, self.held, self.release = path, threading.Event(), threading.Event()

    def _run(self):
        con = sqlite3.connect(self.path, timeout=0.1, isolation_level=None)
        con.execute("BEGIN IMMEDIATE")
        self.held.set()
        self.release.wait(30)
        con.execute("ROLLBACK")
        con.close()

    def __enter__(self):
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        assert self.held.wait(10)
        return self

    def release_after(self, seconds: float):
        threading.Timer(seconds, self.release.set).start()

    def __exit__(self, *exc):
        self.release.set()
        self.thread.join(10)


@pytest.fixture
def db(tmp_path):
    path = tmp_path / "hvcb.sqlite3"
    url = f"sqlite:///{path}"
    upgrade(url)
    return str(path), url


def test_the_store_is_in_wal_with_a_busy_timeout(db):
    _, url = db
    eng = make_engine(url, sqlite_timeout_s=2.5)
    with eng.connect() as c:
        assert c.execute(text("PRAGMA journal_mode")).scalar() == "wal"
        assert c.execute(text("PRAGMA busy_timeout")).scalar() == 2500
    eng.dispose()


def test_a_reader_is_never_blocked_by_a_writer(db):
    path, url = db
    eng = make_engine(url, sqlite_timeout_s=0.05)
    with Writer(path):
        with eng.connect() as c:  # WAL: the read answers while the write lock is held
            assert c.execute(text("SELECT count(*) FROM api_keys")).scalar() == 0
    eng.dispose()


def test_a_write_past_the_busy_timeout_is_retried_until_the_writer_lets_go(db):
    path, url = db
    eng = make_engine(url, sqlite_timeout_s=0.1)

    def work():
        with eng.begin() as c:
            c.execute(text("CREATE TABLE IF NOT EXISTS probe (x INTEGER)"))
            c.execute(text("INSERT INTO probe VALUES (1)"))
            return c.execute(text("SELECT count(*) FROM probe")).scalar()

    with Writer(path) as w:
        with pytest.raises(OperationalError) as caught:  # without the retry: "database is locked"
            work()
        assert is_locked(caught.value)
        w.release_after(0.4)
        waits = []
        assert retry_locked(work, first_wait_s=0.2, sleep=lambda s: (waits.append(s), threading.Event().wait(s))) == 1
    assert waits and waits == sorted(waits)  # it waited, doubling
    eng.dispose()


def test_the_retry_is_bounded_and_other_errors_are_not_retried(db):
    path, url = db
    eng = make_engine(url, sqlite_timeout_s=0.05)
    calls = []

    def locked():
        calls.append(1)
        with eng.begin() as c:
            c.execute(text("CREATE TABLE probe2 (x INTEGER)"))

    with Writer(path):
        with pytest.raises(OperationalError):
            retry_locked(locked, retries=2, sleep=lambda s: None)
    assert len(calls) == 3
    calls.clear()

    def wrong():
        calls.append(1)
        with eng.begin() as c:
            c.execute(text("SELECT * FROM no_such_table"))

    with pytest.raises(OperationalError, match="no such table"):
        retry_locked(wrong, sleep=lambda s: None)
    assert len(calls) == 1
    eng.dispose()


def test_a_sign_in_while_a_writer_holds_the_lock_past_the_busy_timeout_gets_in(tmp_path):
    from tests.service.conftest import make_settings, running_app

    path = tmp_path / "data" / "hvcb.sqlite3"
    (tmp_path / "data").mkdir()
    url = f"sqlite:///{path}"
    upgrade(url)
    settings = make_settings(tmp_path, url, server={"auth_free_failures": 100_000, "sqlite_busy_s": 0.2})
    with running_app(settings) as (app, client, keys):
        form = client.get("/signin")
        token = re.search(r'name="csrf_token" value="([^"]+)"', form.text).group(1)
        with Writer(str(path)) as w:
            w.release_after(0.8)  # four busy timeouts: without the retry this sign-in was a 503
            r = client.post("/signin", data={"api_key": keys["reader"], "csrf_token": token, "next": "/"},
                            follow_redirects=False)
        assert r.status_code == 303, r.text
        assert client.get("/", follow_redirects=False).status_code == 200
