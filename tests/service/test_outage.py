"""Database outage of 30 s while operations arrive: the captures are spooled, and the service's
own spool thread stores them after recovery, none lost or duplicated.

SQLite: the file is locked by an exclusive transaction. PostgreSQL: the service reaches the
server through a TCP proxy on loopback, which is stopped (connections cut, port refusing) and
started again; the real server keeps running.
"""

from __future__ import annotations

import asyncio
import socket
import sqlite3
import threading
import time

import pytest
from sqlalchemy import func, select

from conftest import make_settings, synth
from service.jobs.ingest import Monitor
from service.storage import crud
from service.storage.db import make_engine, session_factory
from service.storage.models import FitRow, OperationRow
from service.workers import make_executor

OUTAGE_S = 30.0
EVERY_S = 2.5  # an operation arrives this often during the outage


class TcpProxy:
    """A loopback TCP forwarder that can be stopped (listener closed, connections cut) and restarted."""

    def __init__(self, target: tuple[str, int]):
        self.target = target
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            self.port = s.getsockname()[1]
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, name="pg-proxy", daemon=True)
        self.server = None
        self.writers: set = set()

    def start(self) -> None:
        if not self.thread.is_alive():
            self.thread.start()
        asyncio.run_coroutine_threadsafe(self._listen(), self.loop).result(10)

    def stop(self) -> None:
        asyncio.run_coroutine_threadsafe(self._close(), self.loop).result(10)

    def shutdown(self) -> None:
        self.stop()
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(timeout=10)
        self.loop.close()

    async def _listen(self):
        self.server = await asyncio.start_server(self._client, "127.0.0.1", self.port, reuse_address=True)

    async def _close(self):
        if self.server is not None:
            self.server.close()
            await self.server.wait_closed()
            self.server = None
        for w in list(self.writers):
            w.transport.abort()
        self.writers.clear()

    async def _client(self, reader, writer):
        try:
            up_reader, up_writer = await asyncio.open_connection(*self.target)
        except OSError:
            writer.transport.abort()
            return
        self.writers |= {writer, up_writer}

        async def pipe(src, dst):
            try:
                while data := await src.read(65536):
                    dst.write(data)
                    await dst.drain()
            except (OSError, asyncio.CancelledError):
                pass
            finally:
                dst.transport.abort()

        await asyncio.gather(pipe(reader, up_writer), pipe(up_reader, writer))
        self.writers -= {writer, up_writer}


def _arrive_during_outage(monitor, breaker, seed0):
    """Operations arriving while the database is down; returns the ingest results."""
    results, t0, i = [], time.monotonic(), 0
    while time.monotonic() - t0 < OUTAGE_S:
        results.append(monitor.ingest(synth(breaker, "open", seed0 + i), breaker_id=1, operation="open"))
        i += 1
        time.sleep(EVERY_S)
    return results


def _wait_stored(monitor, Session, keys, timeout=60):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with Session() as s:
            fits = list(s.scalars(select(FitRow)))
        if len(monitor.spool) == 0 and len(fits) >= len(keys) and all(f.status in ("done", "failed") for f in fits):
            return fits
        time.sleep(0.1)
    raise AssertionError(f"after recovery: {len(monitor.spool)} still spooled, {len(fits)} fits")


def _check_none_lost_or_duplicated(Session, results, fits):
    keys = {r.capture_key for r in results}
    with Session() as s:
        stored = list(s.scalars(select(OperationRow.capture_key)))
        n_ops = s.scalar(select(func.count()).select_from(OperationRow))
    assert len(results) >= 10 and all(r.spooled for r in results[1:])
    assert sorted(stored) == sorted(keys) and n_ops == len(keys)  # every capture once
    assert len(fits) == len(keys) and all(f.status == "done" and f.results_stored == 1 for f in fits)


def test_sqlite_locked_30s_while_operations_arrive_spool_thread_stores_all(tmp_path, db_url, breaker, caplog):
    if not db_url.startswith("sqlite"):
        pytest.skip("the SQLite outage; PostgreSQL has the proxy test")
    settings = make_settings(tmp_path, db_url, spool_retry_s=1.0)
    engine = make_engine(db_url, sqlite_timeout_s=0.5)
    Session = session_factory(engine)
    with Session() as s, s.begin():
        crud.register_breaker_file(s, path=settings.breakers[0])
    monitor = Monitor(settings, Session, make_executor(settings))
    monitor.start()
    try:
        locker = sqlite3.connect(db_url.split("///", 1)[1], timeout=0.1)
        locker.execute("BEGIN EXCLUSIVE")
        try:
            results = _arrive_during_outage(monitor, breaker, 100)
            assert len(monitor.spool) == len(results) and not monitor.db_ok
        finally:
            locker.rollback()
            locker.close()
        fits = _wait_stored(monitor, Session, results)  # nobody calls drain_spool: the service's thread does
        _check_none_lost_or_duplicated(Session, results, fits)
        said = [r.getMessage() for r in caplog.records if r.name == "hvcb.monitor"]
        assert "database unavailable (database is locked); spooling captures until it is back" in said
        assert "database back; storing spooled captures" in said  # the operator sees it end, too
    finally:
        monitor.stop()
        engine.dispose()


def test_postgres_unreachable_30s_while_operations_arrive_spool_thread_stores_all(tmp_path, db_url, breaker):
    if db_url.startswith("sqlite"):
        pytest.skip("the PostgreSQL outage; SQLite has the lock test")
    from sqlalchemy.engine import make_url

    url = make_url(db_url)
    proxy = TcpProxy((url.host or "127.0.0.1", url.port or 5432))
    proxy.start()
    via_proxy = url.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
    settings = make_settings(tmp_path, via_proxy, spool_retry_s=1.0)
    engine = make_engine(via_proxy)
    Session = session_factory(engine)
    try:
        with Session() as s, s.begin():
            crud.register_breaker_file(s, path=settings.breakers[0])
        monitor = Monitor(settings, Session, make_executor(settings))
        monitor.start()
        try:
            proxy.stop()  # the database server is gone for the service
            results = _arrive_during_outage(monitor, breaker, 200)
            assert len(monitor.spool) == len(results) and not monitor.db_ok
            proxy.start()
            fits = _wait_stored(monitor, Session, results)
            _check_none_lost_or_duplicated(Session, results, fits)
        finally:
            monitor.stop()
    finally:
        engine.dispose()
        from service.storage.db import cached_engine

        cached_engine.cache_clear()  # the inline worker's engine points at the proxy
        proxy.shutdown()
