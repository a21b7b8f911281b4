"""Is the database at this code's migration? A sentence that says what to run when it is not."""

from __future__ import annotations

from .db import current_revision, head_revision


class NotMigrated(RuntimeError):
    """The database's Alembic revision is not this code's head."""


def check_schema(engine) -> None:
    """Raise ``NotMigrated`` (with the command that fixes it) unless the database is at head."""
    have, want = current_revision(engine), head_revision()
    if have != want:
        raise NotMigrated(f"the database is at migration {have or 'none'}, this code needs {want}: "
                          f"run `hvcb migrate` (hvcb serve and hvcb demo do it for you)")
