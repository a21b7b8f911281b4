"""A Celery fit task that meets a transient database outage retries and lands exactly once.

The worker reaches PostgreSQL through a proxy the test cuts in the middle of the fit: the
claim has committed, the result cannot be stored. The task must retry (bounded, with backoff)
until the database is back, and the fit must end `done` with one set of parameter rows.
"""

from __future__ import annotations

import os
import time
import uuid

import pytest
from sqlalchemy import func, select, text
from sqlalchemy.engine import make_url

from conftest import PG_URL, REDIS_URL, _reachable, synth
from service.jobs.ingest import Monitor
from service.settings import load_settings
from service.storage import crud
from service.storage.db import make_engine, session_factory, upgrade
from service.storage.models import FitRow, ParameterValueRow
from service.workers import make_executor
from tcp_proxy import CuttableProxy
from test_celery import ROOT, HERE, CeleryWorker, _redis_or_skip

pytestmark = [pytest.mark.redis, pytest.mark.postgres]


@pytest.fixture
def outage_lane(tmp_path):
    client = _redis_or_skip()
    if not PG_URL or _reachable(PG_URL, 5432):
        pytest.skip("database-outage lane off: needs PostgreSQL (HVCB_TEST_POSTGRES_URL) to cut")
    admin = make_engine(PG_URL)
    name = f"hvcb_outage_{os.getpid()}_{uuid.uuid4().hex[:6]}"
    with admin.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"'))
    direct = make_url(PG_URL).set(database=name)
    upgrade(direct.render_as_string(hide_password=False))
    proxy = CuttableProxy((direct.host or "127.0.0.1", direct.port or 5432))
    via_proxy = direct.set(host="127.0.0.1", port=proxy.port).render_as_string(hide_password=False)
    tag = uuid.uuid4().hex[:10]
    prefix, queue = f"hvcb-outage-{tag}:", f"hvcb-outage-{tag}"
    data_dir = tmp_path / "data"
    data_dir.mkdir()
    slow = tmp_path / "slow"
    env = {k: v for k, v in os.environ.items() if not k.startswith("HVCB_") and k != "DATABASE_URL"}
    env.update(HVCB_BROKER_URL=REDIS_URL, DATABASE_URL=via_proxy, HVCB_DATA_DIR=str(data_dir),
               HVCB_CELERY_QUEUE=queue, HVCB_CELERY_KEY_PREFIX=prefix,
               HVCB_FIT_FUNCTION="fit_doubles:celery_double", HVCB_TEST_SLOW_FILE=str(slow),
               PYTHONPATH=os.pathsep.join([str(HERE), str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    # The service side talks to the database directly: only the worker's link is cut.
    settings = load_settings(data_dir=data_dir, database_url=direct.render_as_string(hide_password=False),
                             broker_url=REDIS_URL, executor="celery", celery_queue=queue,
                             celery_key_prefix=prefix, bootstrap_admin_key=None,
                             fit_function="fit_doubles:celery_double")
    engine = make_engine(settings.database_url)
    Session = session_factory(engine)
    with Session() as s, s.begin():
        crud.register_breaker_file(s, path=settings.breakers[0])
    worker = CeleryWorker(env, tmp_path / "worker.log", f"hvcb-outage-{tag}")
    monitor = None
    try:
        worker.start()
        monitor = Monitor(settings, Session, make_executor(settings))
        yield monitor, Session, proxy, worker, slow
    finally:
        if monitor is not None:
            monitor.stop()
        worker.stop()
        proxy.close()
        engine.dispose()
        with admin.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()
        keys = list(client.scan_iter(match=f"{prefix}*", count=500))
        if keys:
            client.delete(*keys)
        client.close()


def _fit(Session, op_id):
    with Session() as s:
        return s.scalar(select(FitRow).where(FitRow.operation_id == op_id).execution_options(populate_existing=True))


def _until(predicate, timeout, what):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def test_the_database_cut_mid_fit_is_retried_and_the_result_lands_once(outage_lane, breaker):
    monitor, Session, proxy, worker, slow = outage_lane
    monitor.executor.start()
    slow.touch()  # the fit pauses 2 s: the cut falls inside it
    op_id = monitor.ingest(synth(breaker, "open", 77), breaker_id=1, operation="open").operation_id
    _until(lambda: _fit(Session, op_id).status == "running", 60, "the worker to claim the fit")
    proxy.cut()
    slow.unlink()
    # the fit ends while the database is gone: its store fails and the task schedules a retry
    _until(lambda: "Retry in" in worker.log(), 180, "the task to retry while the database is gone")
    proxy.restore()
    fit = _until(lambda: (f := _fit(Session, op_id)).status in ("done", "failed") and f, 180, "the fit to land")
    assert fit.status == "done", fit.failure_reason
    assert proxy.refused >= 1  # the worker did try while the database was gone
    assert "Retry in" in worker.log()  # ... and Celery's bounded retry, not a restart, brought it back
    with Session() as s:
        rows = s.scalar(select(func.count()).select_from(ParameterValueRow)
                        .where(ParameterValueRow.operation_id == op_id))
    assert rows == len(fit.parameters)  # one result: no parameter stored twice
