"""The Celery lane: the job tests of the local pool, through a real Celery worker on a real Redis.

Needs HVCB_TEST_REDIS_URL (e.g. redis://127.0.0.1:6379/0). One worker process
(``celery -A service.workers.celery_app worker --pool=prefork --concurrency=1``) serves the whole
session, on the PostgreSQL database when HVCB_TEST_POSTGRES_URL answers, else on a SQLite file it
shares with the test. Its queue and every Redis key carry a prefix unique to the session; the keys
are deleted at the end.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import pytest
from sqlalchemy import delete, func, select

from conftest import PG_URL, REDIS_URL, _reachable, synth
from service.jobs.ingest import Monitor
from service.settings import load_settings
from service.storage import crud
from service.storage.db import make_engine, session_factory, upgrade
from service.storage.models import AlarmRow, DriftStateRow, FitRow, OperationRow, ParameterValueRow
from service.storage.scratch import scratch_pg_database
from service.workers import make_executor

pytestmark = pytest.mark.redis

HERE = Path(__file__).parent
ROOT = HERE.parents[1]


def _redis_or_skip():
    if not REDIS_URL:
        pytest.skip("Celery lane off: HVCB_TEST_REDIS_URL is empty (unset, it is redis://127.0.0.1:6379/0)")
    import redis

    try:
        client = redis.Redis.from_url(REDIS_URL, socket_connect_timeout=1, socket_timeout=2)
        client.ping()
    except Exception as exc:  # noqa: BLE001 - any failure means the lane cannot run
        pytest.skip(f"Celery lane off: Redis at {REDIS_URL} does not answer ({exc})")
    return client


class CeleryWorker:
    """A ``celery worker`` subprocess in its own process group."""

    def __init__(self, env: dict, log_path: Path, name: str):
        self.env, self.log_path, self.name = env, log_path, name
        self.proc: subprocess.Popen | None = None

    def start(self, timeout: float = 90.0) -> None:
        self._log = open(self.log_path, "ab")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "celery", "-A", "service.workers.celery_app", "worker", "--pool=prefork",
             "--concurrency=1", "--without-gossip", "--without-mingle", "--without-heartbeat",
             "--loglevel=INFO", "-n", f"{self.name}@%h"],
            cwd=ROOT, env=self.env, stdout=self._log, stderr=subprocess.STDOUT, start_new_session=True)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise AssertionError(f"celery worker exited ({self.proc.returncode}):\n{self.log()[-3000:]}")
            if f"{self.name}@" in self.log() and " ready." in self.log():
                return
            time.sleep(0.1)
        raise AssertionError(f"celery worker not ready after {timeout} s:\n{self.log()[-3000:]}")

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def pool_pids(self) -> list[int]:
        """The prefork pool's processes (children of the worker's main process)."""
        path = Path(f"/proc/{self.proc.pid}/task/{self.proc.pid}/children")
        return [int(p) for p in path.read_text().split()]

    def stop(self) -> None:
        if self.proc is None:
            return
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)  # warm shutdown
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=10)
        try:  # stray pool processes of the group
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self._log.close()
        self.proc = None


class Lane:
    def __init__(self, url, data_dir, settings_kw, worker, slow_flag):
        self.url, self.data_dir, self.settings_kw = url, data_dir, settings_kw
        self.worker, self.slow_flag = worker, slow_flag
        self.engine = make_engine(url)
        self.Session = session_factory(self.engine)

    def settings(self, **kw):
        return load_settings(**{**self.settings_kw, **kw})

    def clear(self) -> None:
        with self.Session() as s, s.begin():
            for table in (ParameterValueRow, AlarmRow, DriftStateRow, FitRow, OperationRow):
                s.execute(delete(table))


@pytest.fixture(scope="session")
def celery_lane(tmp_path_factory):
    client = _redis_or_skip()
    base = tmp_path_factory.mktemp("celery-lane")
    data_dir = base / "data"
    data_dir.mkdir()
    tag = uuid.uuid4().hex[:10]
    scratch = contextlib.ExitStack()
    if PG_URL and _reachable(PG_URL, 5432) is None:
        url = scratch.enter_context(scratch_pg_database(PG_URL, "hvcb_celery"))
    else:
        url = f"sqlite:///{data_dir / 'hvcb.sqlite3'}"
    upgrade(url)
    prefix, queue = f"hvcb-test-{tag}:", f"hvcb-test-{tag}"
    slow_flag = base / "slow"
    settings_kw = dict(data_dir=data_dir, database_url=url, broker_url=REDIS_URL, executor="celery",
                       celery_queue=queue, celery_key_prefix=prefix, bootstrap_admin_key=None,
                       fit_function="fit_doubles:celery_double")
    env = {k: v for k, v in os.environ.items() if not k.startswith("HVCB_") and k != "DATABASE_URL"}
    env.update(HVCB_BROKER_URL=REDIS_URL, DATABASE_URL=url, HVCB_DATA_DIR=str(data_dir),
               HVCB_CELERY_QUEUE=queue, HVCB_CELERY_KEY_PREFIX=prefix, HVCB_FIT_FUNCTION="fit_doubles:celery_double",
               HVCB_TEST_SLOW_FILE=str(slow_flag),
               PYTHONPATH=os.pathsep.join([str(HERE), str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    worker = CeleryWorker(env, base / "worker.log", f"hvcb-test-{tag}")
    lane = Lane(url, data_dir, settings_kw, worker, slow_flag)
    with lane.Session() as s, s.begin():
        crud.register_breaker_file(s, path=lane.settings().breakers[0])
    try:
        worker.start()
        yield lane
    finally:
        worker.stop()
        lane.engine.dispose()
        keys = list(client.scan_iter(match=f"{prefix}*", count=500))
        if keys:
            client.delete(*keys)
        client.close()
        scratch.close()  # drops the PostgreSQL database, if one was made


@pytest.fixture
def lane(celery_lane):
    celery_lane.clear()
    celery_lane.slow_flag.unlink(missing_ok=True)
    made = []

    def monitor(**kw):
        settings = celery_lane.settings(**kw)
        m = Monitor(settings, celery_lane.Session, make_executor(settings))
        made.append(m)
        return m

    celery_lane.monitor = monitor
    yield celery_lane
    celery_lane.slow_flag.unlink(missing_ok=True)
    for m in made:
        m.stop()


def _wait(Session, op_ids, timeout=120):
    deadline = time.monotonic() + timeout
    fits = []
    while time.monotonic() < deadline:
        with Session() as s:
            fits = list(s.scalars(select(FitRow).where(FitRow.operation_id.in_(op_ids))))
        if len(fits) >= len(op_ids) and all(f.status in ("done", "failed") for f in fits):
            return fits
        time.sleep(0.1)
    raise AssertionError(f"fits not finished: {[(f.operation_id, f.status) for f in fits]}")


def test_celery_failed_fit_stores_reason_and_never_blocks_the_queue(lane, breaker):
    monitor = lane.monitor()
    monitor.start()
    assert monitor.executor.kind == "celery"
    flat = synth(breaker, "open", 1)
    flat = type(flat)(**{**flat.__dict__, "travel": np.full_like(flat.travel, 0.01)})
    bad = monitor.ingest(flat, breaker_id=1, operation="open").operation_id
    good = monitor.ingest(synth(breaker, "open", 2), breaker_id=1, operation="open").operation_id
    fits = {f.operation_id: f for f in _wait(lane.Session, [bad, good])}
    assert fits[bad].status == "failed" and "barely moves" in fits[bad].failure_reason
    assert fits[good].status == "done" and fits[good].parameters["DO"] > 30
    assert fits[good].worker and fits[good].worker.split(":")[-1] != str(os.getpid())  # ran in the worker


def test_celery_job_delivered_twice_lands_result_once(lane, breaker):
    monitor = lane.monitor()
    monitor.start()
    op = monitor.ingest(synth(breaker, "open", 4), breaker_id=1, operation="open").operation_id
    monitor.executor.submit(op)  # a duplicate delivery of the same job
    monitor.executor.submit(op)
    (fit,) = _wait(lane.Session, [op])
    time.sleep(1.0)  # let the duplicates run too: they must find the fit done
    with lane.Session() as s:
        fit = crud.get_fit(s, operation_id=op)
        n_values = len(crud.parameter_trend(s, breaker_id=1, name="DO"))
    assert fit.status == "done" and fit.attempts == 1 and fit.results_stored == 1 and n_values == 1


def test_celery_worker_killed_mid_fit_is_retried_and_lands_once(lane, breaker):
    monitor = lane.monitor()
    monitor.start()
    lane.slow_flag.write_text("pause each fit")
    op = monitor.ingest(synth(breaker, "open", 5), breaker_id=1, operation="open").operation_id
    deadline = time.monotonic() + 60
    status = None
    while time.monotonic() < deadline:
        with lane.Session() as s:
            status = crud.get_fit(s, operation_id=op).status
        if status == "running":
            break
        time.sleep(0.02)
    assert status == "running"
    pids = lane.worker.pool_pids()
    assert pids
    for pid in pids:
        os.kill(pid, signal.SIGKILL)  # the pool process dies in the middle of the fit
    lane.slow_flag.unlink()
    (fit,) = _wait(lane.Session, [op])
    with lane.Session() as s:
        n_fits = s.scalar(select(func.count()).select_from(FitRow).where(FitRow.operation_id == op))
        n_values = s.scalar(select(func.count()).select_from(ParameterValueRow)
                            .where(ParameterValueRow.operation_id == op, ParameterValueRow.name == "DO"))
    assert fit.status == "done" and fit.attempts == 2 and fit.results_stored == 1
    assert n_fits == 1 and n_values == 1
    assert "WorkerLostError" in lane.worker.log() or "exited" in lane.worker.log()
    assert lane.worker.proc.poll() is None  # the worker itself lives on with a new pool process


def test_celery_service_crash_then_restart_fits_every_capture_once(lane, breaker, tmp_path):
    n = 4
    lane.slow_flag.write_text("pause each fit")  # keep work pending when the service dies
    child = subprocess.Popen([sys.executable, str(HERE / "crash_child.py"), str(lane.data_dir.parent), lane.url, str(n),
                              "--celery", lane.settings_kw["celery_queue"], lane.settings_kw["celery_key_prefix"]],
                             stdout=subprocess.PIPE, text=True, start_new_session=True,
                             env={**os.environ, "HVCB_TEST_REDIS_URL": REDIS_URL})
    try:
        assert child.stdout.readline().strip() == "ingested"
    finally:
        os.killpg(child.pid, signal.SIGKILL)
        child.wait(timeout=30)
        child.stdout.close()
    with lane.Session() as s:
        pending_before = crud.queue_depth(s)
        op_ids = list(s.scalars(select(OperationRow.id)))
    assert pending_before >= 1 and len(op_ids) == n
    lane.slow_flag.unlink()
    monitor = lane.monitor()
    monitor.start()  # re-queues what was pending or running: the worker gets some jobs twice
    fits = _wait(lane.Session, op_ids)
    time.sleep(1.0)  # let any duplicate deliveries run out
    with lane.Session() as s:
        fits = list(s.scalars(select(FitRow)))
        n_ops = s.scalar(select(func.count()).select_from(OperationRow))
        n_values = s.scalar(select(func.count()).select_from(ParameterValueRow).where(ParameterValueRow.name == "DO"))
    assert n_ops == n and len(fits) == n and n_values == n
    assert all(f.status == "done" and f.results_stored == 1 for f in fits)


def test_celery_breaker_diagnosis_runs_in_a_worker(lane, breaker):
    """A breaker-level diagnosis (issue 20) is the task hvcb.breaker_diagnosis: the worker runs
    the real diagnosis on two stored openings and stores its answer; a second delivery of the
    same task leaves the stored answer alone."""
    from service.storage import crud_diagnoses
    from service.storage.models import BreakerDiagnosisRow
    from service.workers.breaker_diagnoses import BreakerDiagnosisRunner

    monitor = lane.monitor()
    ops = [monitor.ingest(synth(breaker, "open", seed=60 + i), breaker_id=1, operation="open").operation_id
           for i in range(2)]
    with lane.Session() as s:
        key = crud_diagnoses.selection_key(breaker_id=1, kind="open", operation_ids=ops)
        row, created = crud_diagnoses.insert(s, breaker_id=1, kind="open", last=2, operation_ids=ops, skipped=[],
                                             key=key, requested_by="celery test", key_id=None, role="reader")
        rid = row.id
    assert created
    runner = BreakerDiagnosisRunner(lane.settings())
    try:
        runner.submit(rid)
        deadline = time.monotonic() + 240
        while True:
            with lane.Session() as s:
                row = s.get(BreakerDiagnosisRow, rid)
                if row.status in ("done", "failed"):
                    break
            assert time.monotonic() < deadline, f"diagnosis still {row.status}:\n{lane.worker.log()[-2000:]}"
            time.sleep(0.2)
        assert row.status == "done", row.failure_reason
        captures = row.result["captures"]  # a count in the issue-20 shape, a list per capture before it
        assert row.result["operation_ids"] == ops and (captures if isinstance(captures, int) else len(captures)) == 2
        finished = row.finished_at
        runner.submit(rid)  # delivered again: the job finds it done
        time.sleep(2.0)
        with lane.Session() as s:
            assert s.get(BreakerDiagnosisRow, rid).finished_at == finished
    finally:
        runner.shutdown()
