"""Storage test fixtures: a fresh database of each kind, NOT migrated (the tests choose the
revision). SQLite always; PostgreSQL when HVCB_TEST_POSTGRES_URL is set and answers."""

from __future__ import annotations

import os

import pytest

from service.storage.scratch import scratch_pg_database, unreachable

PG_URL = os.environ.get("HVCB_TEST_POSTGRES_URL")


def _pg_skip_reason() -> str | None:
    if not PG_URL:
        return "PostgreSQL lane off: HVCB_TEST_POSTGRES_URL is empty (unset, it is 127.0.0.1:5432/test)"
    why = unreachable(PG_URL)
    return f"PostgreSQL lane off: {why}" if why else None


@pytest.fixture(scope="session")
def pg_database():
    """A PostgreSQL database created for this session and dropped at the end."""
    why = _pg_skip_reason()
    if why:
        print(why)
        pytest.skip(why)
    yield from temporary_pg_database("hvcb_storage")


def temporary_pg_database(prefix: str):
    """A scratch database on the PostgreSQL lane's server (yields its URL; dropped afterwards)."""
    with scratch_pg_database(PG_URL, prefix) as url:
        yield url


@pytest.fixture(params=["sqlite", pytest.param("postgres", marks=pytest.mark.postgres)])
def empty_db_url(request, tmp_path):
    """An empty database (no tables) of each kind."""
    if request.param == "sqlite":
        (tmp_path / "data").mkdir(exist_ok=True)
        return f"sqlite:///{tmp_path / 'data' / 'hvcb.sqlite3'}"
    from sqlalchemy import text

    from service.storage.db import make_engine

    url = request.getfixturevalue("pg_database")
    eng = make_engine(url)
    with eng.begin() as conn:
        conn.execute(text("DROP SCHEMA public CASCADE"))
        conn.execute(text("CREATE SCHEMA public"))
    eng.dispose()
    return url
