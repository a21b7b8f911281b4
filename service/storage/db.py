"""Engine and session factories, and the migration entry points (Alembic, not create_all)."""

from __future__ import annotations

import time
from functools import lru_cache
from pathlib import Path
from typing import Callable, TypeVar

from sqlalchemy import create_engine, event
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session, sessionmaker

MIGRATIONS_DIR = Path(__file__).resolve().parents[2] / "migrations"


class DatabaseUnavailable(RuntimeError):
    """The database cannot be reached or is locked; the caller spools and retries."""


T = TypeVar("T")
# SQLite's answers when another connection holds the write lock longer than the busy timeout.
_LOCKED = ("database is locked", "database table is locked", "database is busy")
LOCK_RETRIES = 3          # attempts after the first...
LOCK_RETRY_FIRST_S = 0.25  # ...waiting 0.25, 0.5, 1 s between them (on top of each busy timeout)


def is_locked(exc: BaseException) -> bool:
    """Did SQLite refuse because another connection held its write lock (not a real fault)?"""
    return any(m in str(exc).lower() for m in _LOCKED)


def retry_locked(work: Callable[[], T], *, retries: int = LOCK_RETRIES, first_wait_s: float = LOCK_RETRY_FIRST_S,
                 sleep: Callable[[float], None] = time.sleep) -> T:
    """``work()`` (a whole unit of work: it opens its own session and transaction) run again when
    SQLite answered "database is locked", a bounded number of times with a doubling wait. A writer
    holding the lock past the busy timeout (``make_engine``'s ``sqlite_timeout_s``) then costs the
    caller a longer wait, never a 503; any other error, and the last locked one, propagate."""
    from sqlalchemy.exc import OperationalError

    wait = first_wait_s
    for attempt in range(retries + 1):
        try:
            return work()
        except OperationalError as exc:
            if attempt == retries or not is_locked(exc):
                raise
        sleep(wait)
        wait *= 2
    raise AssertionError("unreachable")


def make_engine(url: str, *, sqlite_timeout_s: float = 10.0, pool_size: int = 10, pool_timeout_s: float = 10.0) -> Engine:
    """An engine for ``url``. SQLite gets WAL (readers never wait for a writer), foreign keys and
    a bounded lock wait (``sqlite_timeout_s``, SQLite's busy timeout [s]: a writer waits this long
    for another writer's lock before "database is locked"; ``retry_locked`` retries the unit of work).

    ``pool_size``: connections kept (the service passes its thread count plus its background
    threads, ``[server]``); no overflow, so a caller waits at most ``pool_timeout_s`` and then
    gets ``sqlalchemy.exc.TimeoutError`` (answered 503, never 500)."""
    if url.startswith("sqlite"):
        path = url.split("///", 1)[-1]
        if path and path != ":memory:":
            Path(path).parent.mkdir(parents=True, exist_ok=True)
        _private_file(path)
        engine = create_engine(url, connect_args={"timeout": sqlite_timeout_s, "check_same_thread": False},
                               pool_size=pool_size, max_overflow=0, pool_timeout=pool_timeout_s)

        @event.listens_for(engine, "connect")
        def _pragmas(dbapi_conn, _record):
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA foreign_keys=ON")
            cur.execute(f"PRAGMA busy_timeout={int(sqlite_timeout_s * 1000)}")
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA synchronous=NORMAL")
            cur.close()
            _private_file(path)
            for suffix in ("-wal", "-shm"):
                _private_file(path + suffix)
        return engine
    return create_engine(url, pool_pre_ping=True, pool_size=pool_size, max_overflow=0, pool_timeout=pool_timeout_s,
                         connect_args={"connect_timeout": 5} if "psycopg" in url or url.startswith("postgres") else {})


def _private_file(path: str) -> None:
    """Mode 0600 on a database file, whatever the umask (docs/security.md: file modes)."""
    import os

    if path and path != ":memory:" and os.path.exists(path):
        try:
            os.chmod(path, 0o600)
        except OSError:
            pass


@lru_cache(maxsize=8)
def cached_engine(url: str) -> Engine:
    """One engine per URL per process (worker processes call this)."""
    return make_engine(url)


def session_factory(engine: Engine) -> sessionmaker[Session]:
    return sessionmaker(engine, expire_on_commit=False)


def alembic_config(url: str):
    from alembic.config import Config

    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    cfg.set_main_option("sqlalchemy.url", url.replace("%", "%%"))
    cfg.attributes["configure_logging"] = False
    return cfg


def upgrade(url: str, revision: str = "head") -> None:
    """Migrate the database at ``url`` up to ``revision``."""
    from alembic import command

    command.upgrade(alembic_config(url), revision)


def downgrade(url: str, revision: str = "base") -> None:
    from alembic import command

    command.downgrade(alembic_config(url), revision)


def current_revision(engine: Engine) -> str | None:
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()


def head_revision() -> str:
    from alembic.script import ScriptDirectory

    return ScriptDirectory.from_config(alembic_config("sqlite://")).get_current_head()
