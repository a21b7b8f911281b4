"""Storage test fixtures: a fresh database of each kind, NOT migrated (the tests choose the
revision). SQLite always; PostgreSQL when HVCB_TEST_POSTGRES_URL is set and answers."""

from __future__ import annotations

import os
import socket
import uuid

import pytest

PG_URL = os.environ.get("HVCB_TEST_POSTGRES_URL")


def _pg_skip_reason() -> str | None:
    if not PG_URL:
        return ("PostgreSQL lane off: set HVCB_TEST_POSTGRES_URL, e.g. "
                "postgresql+psycopg://postgres@127.0.0.1:5432/test_mine")
    from sqlalchemy.engine import make_url

    u = make_url(PG_URL)
    try:
        with socket.create_connection((u.host or "127.0.0.1", u.port or 5432), timeout=1):
            return None
    except OSError as exc:
        return f"PostgreSQL lane off: {u.host}:{u.port or 5432} does not answer ({exc})"


@pytest.fixture(scope="session")
def pg_database():
    """A PostgreSQL database created for this session and dropped at the end."""
    why = _pg_skip_reason()
    if why:
        print(why)
        pytest.skip(why)
    yield from temporary_pg_database(f"hvcb_storage_{os.getpid()}_{uuid.uuid4().hex[:6]}")


def temporary_pg_database(name: str):
    """Create database ``name`` on the PostgreSQL lane's server, yield its URL, drop it."""
    from sqlalchemy import text
    from sqlalchemy.engine import make_url

    from service.storage.db import make_engine

    admin = make_engine(PG_URL)
    with admin.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"'))
    try:
        yield make_url(PG_URL).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()


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
