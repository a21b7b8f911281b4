"""The exports' keyset pages and the report on PostgreSQL: 2,500 operations (three full chunks and
a part), the same rows as the stored parameters, and a report that renders."""

from __future__ import annotations

import csv
import io
import os

import pytest

from .conftest import BREAKER_FILE

PG_URL = os.environ.get("HVCB_TEST_POSTGRES_URL")
N = 2500

pytestmark = pytest.mark.postgres


@pytest.fixture(scope="module")
def pg_history(tmp_path_factory):
    from service.breaker_file import load_breaker
    from service.settings import load_settings
    from service.storage import crud
    from service.storage.db import make_engine, session_factory, upgrade
    from service.storage.scratch import scratch_pg_database, unreachable

    from .history import bulk_history

    if not PG_URL:
        pytest.skip("PostgreSQL lane off: HVCB_TEST_POSTGRES_URL is empty")
    why = unreachable(PG_URL)
    if why:
        pytest.skip(f"PostgreSQL lane off: {why}")
    with scratch_pg_database(PG_URL, "hvcb_reports") as url:
        upgrade(url)
        data = tmp_path_factory.mktemp("pg-reports")
        settings = load_settings(data_dir=data, database_url=url, broker_url="", executor="inline",
                                 bootstrap_admin_key=None)
        engine = make_engine(url)
        Session = session_factory(engine)
        with Session() as s, s.begin():
            crud.register_breaker_file(s, path=BREAKER_FILE, tag="Q1")
        bulk_history(Session, settings.drift_settings, load_breaker(BREAKER_FILE), capture_path="/nonexistent.cfg",
                     n=N, leak_from=0.9, leak_per_op=0.98)
        try:
            yield Session, settings
        finally:
            engine.dispose()


def test_the_operations_csv_pages_through_postgresql(pg_history):
    from sqlalchemy import select

    from service.reports.exports import CHUNK_ROWS, alarm_chunks, operation_chunks
    from service.storage.models import AlarmRow, ParameterValueRow

    Session, _ = pg_history
    chunks = list(operation_chunks(Session, breaker_id=1))
    assert len(chunks) == 1 + -(-N // CHUNK_ROWS)
    rows = list(csv.DictReader(io.StringIO("".join(chunks))))
    assert len(rows) == N and len({r["operation_id"] for r in rows}) == N
    assert [r["occurred_at [UTC]"] for r in rows] == sorted(r["occurred_at [UTC]"] for r in rows)
    with Session() as s:
        stored = {op: v for op, v in s.execute(select(ParameterValueRow.operation_id, ParameterValueRow.value)
                                               .where(ParameterValueRow.name == "DO"))}
        alarm_ids = sorted(s.scalars(select(AlarmRow.id)))
    assert {int(r["operation_id"]): float(r["DO [s^-1]"]) for r in rows if r["DO [s^-1]"]} == stored
    alarms = list(csv.DictReader(io.StringIO("".join(alarm_chunks(Session, breaker_id=1)))))
    assert alarm_ids and [int(a["alarm_id"]) for a in alarms] == alarm_ids


def test_the_report_renders_from_postgresql(pg_history):
    from service.reports.content import gather
    from service.reports.pdf import render
    from service.storage import crud

    Session, settings = pg_history
    with Session() as s:
        c = gather(s, breaker=crud.get_breaker(s, breaker_id=1), settings=settings.drift_settings)
    assert c.counts["open"] + c.counts["close"] == N and c.active_alarms
    assert render(c)[:5] == b"%PDF-"
