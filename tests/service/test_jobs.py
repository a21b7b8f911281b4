"""Fit jobs: failures, idempotency, dead workers, crash and restart, database outage."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import func, select

from conftest import make_settings, synth
from service.jobs.fit import JobOptions, run_fit_job
from service.jobs.ingest import Monitor
from service.storage import crud
from service.storage.db import make_engine, session_factory
from service.storage.models import FitRow, OperationRow
from service.workers import make_executor

HERE = Path(__file__).parent


@pytest.fixture
def stack(tmp_path, db_url, request):
    """Monitor + executor on a migrated database with the reference breaker registered."""
    made = []

    def build(**kw):
        settings = make_settings(tmp_path, db_url, **kw)
        engine = make_engine(db_url, sqlite_timeout_s=1.0)
        Session = session_factory(engine)
        with Session() as s, s.begin():
            crud.register_breaker_file(s, path=settings.breakers[0])
        monitor = Monitor(settings, Session, make_executor(settings))
        made.append((monitor, engine))
        return monitor, Session, settings

    yield build
    for monitor, engine in made:
        monitor.stop()
        engine.dispose()


def _wait(Session, n, timeout=90):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with Session() as s:
            fits = list(s.scalars(select(FitRow)))
        if len(fits) >= n and all(f.status in ("done", "failed") for f in fits):
            return fits
        time.sleep(0.05)
    raise AssertionError(f"fits not finished: {[(f.operation_id, f.status) for f in fits]}")


def test_failed_fit_stores_reason_and_never_blocks_the_queue(stack, breaker):
    monitor, Session, _ = stack(fit_function="fit_doubles:fails_without_motion")
    monitor.start()
    flat = synth(breaker, "open", 1)
    flat = type(flat)(**{**flat.__dict__, "travel": np.full_like(flat.travel, 0.01)})
    bad = monitor.ingest(flat, breaker_id=1, operation="open").operation_id
    good = monitor.ingest(synth(breaker, "open", 2), breaker_id=1, operation="open").operation_id
    fits = {f.operation_id: f for f in _wait(Session, 2)}
    assert fits[bad].status == "failed" and "barely moves" in fits[bad].failure_reason
    assert fits[good].status == "done" and fits[good].parameters["DO"] > 30


class _HeldJobs:
    """An executor that holds its jobs: the test runs them itself, when it is ready."""

    def __init__(self):
        self.submitted = []

    def start(self) -> None: ...

    def submit(self, operation_id: int) -> None:
        self.submitted.append(operation_id)

    def shutdown(self, *, wait: bool = True) -> None: ...


def test_corrupted_capture_file_fails_with_checksum_reason(stack, breaker):
    monitor, Session, settings = stack()
    monitor.executor = _HeldJobs()  # no background fit may read the file before it is corrupted
    res = monitor.ingest(synth(breaker, "open", 3), breaker_id=1, operation="open")
    with Session() as s:
        path = Path(crud.get_operation(s, operation_id=res.operation_id).capture_path)
    with open(path.with_suffix(".dat"), "r+b") as fh:
        fh.seek(100)
        fh.write(b"\x13\x37")
    assert monitor.executor.submitted == [res.operation_id]
    run_fit_job(res.operation_id, JobOptions.from_settings(settings))
    with Session() as s:
        fit = crud.get_fit(s, operation_id=res.operation_id)
    assert fit.status == "failed" and "checksum" in fit.failure_reason


def test_job_run_twice_lands_result_once(stack, breaker):
    monitor, Session, settings = stack()
    res = monitor.ingest(synth(breaker, "open", 4), breaker_id=1, operation="open")
    options = JobOptions.from_settings(settings)
    first = run_fit_job(res.operation_id, options)
    second = run_fit_job(res.operation_id, options)
    # the inline executor ran the same job in the background too: three runs, one result
    assert second["status"] == "skipped" and not second["landed"]
    assert first["status"] in ("done", "skipped")
    with Session() as s:
        fit = crud.get_fit(s, operation_id=res.operation_id)
        n_values = len(crud.parameter_trend(s, breaker_id=1, name="DO"))
    assert fit.status == "done" and fit.results_stored == 1 and n_values == 1


def test_local_pool_worker_killed_mid_fit_is_retried_and_lands_once(stack, breaker):
    monitor, Session, _ = stack(executor="local", fit_function="fit_doubles:slow_fit")
    monitor.start()
    op = monitor.ingest(synth(breaker, "open", 5), breaker_id=1, operation="open").operation_id
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        with Session() as s:
            if crud.get_fit(s, operation_id=op).status == "running":
                break
        time.sleep(0.02)
    pids = monitor.executor.pids()
    assert pids
    for pid in pids:
        os.kill(pid, signal.SIGKILL)
    (fit,) = _wait(Session, 1)
    assert fit.status == "done" and fit.attempts == 2 and fit.results_stored == 1


def test_crash_with_captures_pending_then_restart_fits_every_capture_once(tmp_path, db_url, breaker):
    n = 4
    child = subprocess.Popen([sys.executable, str(HERE / "crash_child.py"), str(tmp_path), db_url, str(n)],
                             stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert child.stdout.readline().strip() == "ingested"
    finally:
        os.killpg(child.pid, signal.SIGKILL)  # the service and its pool die at once
        child.wait(timeout=30)
        child.stdout.close()
    engine = make_engine(db_url)
    Session = session_factory(engine)
    with Session() as s:
        pending_before = crud.queue_depth(s)
    assert pending_before >= 1  # the crash left work behind
    settings = make_settings(tmp_path, db_url)
    monitor = Monitor(settings, Session, make_executor(settings))
    try:
        monitor.start()  # re-queues what was pending or running
        fits = _wait(Session, n)
    finally:
        monitor.stop()
    with Session() as s:
        n_ops = s.scalar(select(func.count()).select_from(OperationRow))
    engine.dispose()
    assert n_ops == n and len(fits) == n
    assert all(f.status == "done" and f.results_stored == 1 for f in fits)


def test_sqlite_locked_captures_spooled_then_stored_none_lost(stack, breaker, db_url):
    if not db_url.startswith("sqlite"):
        pytest.skip("the lock outage is the SQLite one; PostgreSQL outage is the unreachable-server test")
    monitor, Session, _ = stack()
    monitor.start()
    path = db_url.split("///", 1)[1]
    locker = sqlite3.connect(path, timeout=0.1)
    locker.execute("BEGIN EXCLUSIVE")
    try:
        results = [monitor.ingest(synth(breaker, "open", 10 + i), breaker_id=1, operation="open") for i in range(3)]
        assert all(r.spooled and r.operation_id is None for r in results)
        assert len(monitor.spool) == 3
    finally:
        locker.rollback()
        locker.close()
    deadline = time.monotonic() + 30
    while len(monitor.spool) and time.monotonic() < deadline:
        time.sleep(0.05)
    fits = _wait(Session, 3)
    with Session() as s:
        keys = set(s.scalars(select(OperationRow.capture_key)))
    assert keys == {r.capture_key for r in results}
    assert len(fits) == 3 and all(f.status == "done" for f in fits)


def test_unreachable_database_captures_spooled_then_stored(tmp_path, db_url, breaker):
    """A database server that refuses connections (port 1) while operations arrive, then recovers."""
    settings = make_settings(tmp_path, db_url)
    good = make_engine(db_url)
    with session_factory(good)() as s, s.begin():
        crud.register_breaker_file(s, path=settings.breakers[0])
    down = make_engine("postgresql+psycopg://postgres@127.0.0.1:1/none")
    monitor = Monitor(settings, session_factory(down), make_executor(settings))
    try:
        monitor.executor.start()
        results = [monitor.ingest(synth(breaker, "open", 20 + i), breaker_id=1, operation="open") for i in range(3)]
        assert all(r.spooled for r in results) and len(monitor.spool) == 3
        monitor.Session = session_factory(good)  # the database is back
        assert monitor.drain_spool() == 3 and len(monitor.spool) == 0
        fits = _wait(monitor.Session, 3)
        assert all(f.status == "done" for f in fits)
    finally:
        monitor.stop()
        down.dispose()
        good.dispose()


def test_a_fit_left_running_by_a_dead_worker_is_queued_again_without_a_restart(stack, breaker):
    """A worker machine that vanished leaves its fit `running`; the sweep hands it on after the lease."""
    from datetime import datetime, timedelta, timezone

    from sqlalchemy import delete, update

    from service.storage.models import ParameterValueRow

    monitor, Session, settings = stack(fit_lease_s=60.0)
    monitor.executor.start()
    ops = [monitor.ingest(synth(breaker, "open", 40 + i), breaker_id=1, operation="open").operation_id
           for i in range(2)]
    _wait(Session, 2)
    now = datetime.now(timezone.utc)
    with Session() as s, s.begin():  # op 0 as a dead worker left it; op 1 is a fresh, live claim
        s.execute(delete(ParameterValueRow).where(ParameterValueRow.operation_id == ops[0]))
        s.execute(update(FitRow).where(FitRow.operation_id == ops[0])
                  .values(status="running", attempts=1, started_at=now - timedelta(seconds=61)))
        s.execute(update(FitRow).where(FitRow.operation_id == ops[1])
                  .values(status="running", attempts=1, started_at=now - timedelta(seconds=5)))
    assert monitor.requeue_stale() == 1
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        with Session() as s:
            fit = s.scalar(select(FitRow).where(FitRow.operation_id == ops[0]))
        if fit.status == "done":
            break
        time.sleep(0.05)
    assert fit.status == "done" and fit.attempts == 2
    with Session() as s:
        live = s.scalar(select(FitRow).where(FitRow.operation_id == ops[1]))
        assert live.status == "running" and live.attempts == 1  # within its lease: left alone
    assert monitor.requeue_stale() == 0


def test_the_fitted_curve_is_rebuilt_from_the_parameters_not_stored(stack, breaker):
    """A few kB per operation: the fits row keeps the parameters, the curve is recomputed."""
    from service.estimation import fit_capture
    from service.storage.fit_curve import fit_curve

    monitor, Session, settings = stack()
    monitor.executor.start()
    cap = synth(breaker, "open", 91)
    op_id = monitor.ingest(cap, breaker_id=1, operation="open").operation_id
    (row,) = _wait(Session, 1)
    assert row.status == "done" and row.curve is None
    from service.acquisition.capture_file import read_capture

    with Session() as s:
        stored = read_capture(s.get(OperationRow, op_id).capture_path)  # what the job fitted
    t, fitted = fit_curve(row, stored.t, breaker)
    assert np.array_equal(t, stored.t)
    # The rebuilt curve is the one the fit scored: its RMSE over the window is the stored one.
    w = (stored.t >= row.window_start_s) & (stored.t <= row.window_end_s)
    assert np.sqrt(np.mean((fitted[w] - stored.travel[w]) ** 2)) == pytest.approx(row.rmse_rad, rel=1e-3)
    # ... and an independent fit of the same capture draws the same curve to well within the noise.
    direct = fit_capture(stored, breaker, "open", seed=settings.fit_seed).fitted_travel(stored, breaker)
    assert np.max(np.abs(fitted - direct)[w]) < 0.2 * row.noise_rad
