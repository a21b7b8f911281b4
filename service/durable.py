"""Durable files: nothing is acknowledged before it is on disk.

``write_durably`` is the one way hvcb writes a file that must survive a crash: a temporary file
in the same directory, fsync, an atomic rename over the target, then fsync of the directory so
the rename itself is on disk. A reader sees the old file or the new one, never a torn one.
Used by the COMTRADE writer (captures), the spool (journal), the agent's outbox and backups.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def fsync_dir(directory: str | os.PathLike) -> None:
    """fsync a directory, so that renames and unlinks in it are on disk."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # some platforms cannot open directories; the files are synced already
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def fsync_file(path: str | os.PathLike) -> None:
    """fsync a file written by someone else (e.g. numpy), before it is acknowledged."""
    with open(path, "rb+") as fh:
        os.fsync(fh.fileno())


def write_durably(path: str | os.PathLike, data: bytes | str, *, mode: int = 0o600,
                  sync_dir: bool = True) -> Path:
    """Write ``data`` (str as UTF-8) to ``path`` atomically and durably; return the path.

    ``mode`` is the file's permission bits: 0600 by default, whatever the umask, since captures,
    keys and the journal are the service's alone (docs/security.md). ``sync_dir=False``
    leaves the directory's fsync to the caller, who writes several files and syncs once.
    """
    path = Path(path)
    if isinstance(data, str):
        data = data.encode("utf-8")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    if sync_dir:
        fsync_dir(path.parent)
    return path
