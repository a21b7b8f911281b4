"""Engine and session factories, and the migration entry points (Alembic, not create_all)."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from sqlalchemy import create_engine, event
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session, sessionmaker

MIGRATIONS_DIR = Path(__file__).resolve().parents[2] / "migrations"


class DatabaseUnavailable(RuntimeError):
    """The database cannot be reached or is locked; the caller spools and retries."""


def make_engine(url: str, *, sqlite_timeout_s: float = 5.0, pool_size: int = 10, pool_timeout_s: float = 10.0) -> Engine:
    """An engine for ``url``. SQLite gets WAL, foreign keys and a bounded lock wait.

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
