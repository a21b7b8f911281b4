"""A scratch PostgreSQL database: created on a server, handed out by URL, dropped afterwards.

The one helper the tests and the benchmarks use for a PostgreSQL database of their own (the
service itself never creates databases). The server URL names any database the user may connect
to (e.g. ``postgresql+psycopg://postgres@127.0.0.1:5432/test``); the scratch database lives
beside it under a unique name.
"""

from __future__ import annotations

import os
import socket
import uuid
from collections.abc import Iterator
from contextlib import contextmanager


def unreachable(url: str, default_port: int = 5432) -> str | None:
    """Why the server of ``url`` cannot be reached (a sentence), or None when it answers."""
    from sqlalchemy.engine import make_url

    u = make_url(url)
    try:
        with socket.create_connection((u.host or "127.0.0.1", u.port or default_port), timeout=1):
            return None
    except OSError as exc:
        return f"{u.host}:{u.port or default_port} does not answer ({exc})"


@contextmanager
def scratch_pg_database(server_url: str, prefix: str = "hvcb_scratch") -> Iterator[str]:
    """Create an empty database next to ``server_url``'s, yield its URL, drop it on exit
    (``WITH (FORCE)``: connections a test left open do not keep it alive)."""
    from sqlalchemy import create_engine, text
    from sqlalchemy.engine import make_url

    name = f"{prefix}_{os.getpid()}_{uuid.uuid4().hex[:8]}"
    admin = create_engine(server_url, isolation_level="AUTOCOMMIT")
    try:
        with admin.connect() as conn:
            conn.execute(text(f'CREATE DATABASE "{name}"'))
        try:
            yield make_url(server_url).set(database=name).render_as_string(hide_password=False)
        finally:
            with admin.connect() as conn:
                conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
    finally:
        admin.dispose()
