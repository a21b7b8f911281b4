"""Durable capture files and the spool journal.

A capture is made durable before anything else: its file is written and fsynced, then a
journal entry (one small JSON file per capture under ``spool/pending``) is fsynced. The entry
is removed only once the operation row is committed. While the database is unreachable the
entries pile up; the monitor stores them after recovery. Storing is idempotent on the entry's
key, so a crash between the commit and the removal cannot duplicate an operation.
"""

from __future__ import annotations

import hashlib
import json
import os
import uuid
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from drivers.capture import Capture
from service.durable import fsync_dir, fsync_file, write_durably


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def capture_digest(paths: list[Path]) -> str:
    """SHA-256 over the capture's files (``.cfg`` then ``.dat``, or the one CSV)."""
    h = hashlib.sha256()
    for p in paths:
        h.update(sha256_file(p).encode())
    return h.hexdigest()


def capture_files(path: Path) -> list[Path]:
    path = Path(path)
    if path.suffix.lower() == ".cfg":
        return [path, path.with_suffix(".dat")]
    return [path]


def write_capture_file(capture: Capture, directory: Path, key: str) -> tuple[Path, str]:
    """Write ``capture`` durably under ``directory`` as COMTRADE (CSV when no writer is
    installed); return (main file path, sha256)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    try:
        from service.acquisition.comtrade_writer import write_comtrade
    except ImportError:
        write_comtrade = None
    if write_comtrade is not None:
        main = Path(write_comtrade(capture, directory, key))
    else:
        main = directory / f"{key}.csv"
        t = capture.t
        cols = [t, capture.travel] + ([capture.vibration] if capture.vibration is not None else [])
        header = "t_s,travel_rad" + (",vibration_g" if capture.vibration is not None else "")
        tmp = main.with_suffix(".tmp")
        np.savetxt(tmp, np.column_stack(cols), delimiter=",", header=header, comments="", fmt="%.9g")
        os.replace(tmp, main)
    files = capture_files(main)
    for p in files:
        fsync_file(p)
    fsync_dir(directory)
    return main, capture_digest(files)


class Spool:
    """Journal of captures whose operation row is not committed yet."""

    def __init__(self, directory: Path):
        self.directory = Path(directory) / "pending"
        self.directory.mkdir(parents=True, exist_ok=True)

    @staticmethod
    def new_key() -> str:
        return uuid.uuid4().hex

    def put(self, entry: dict) -> Path:
        key = entry["capture_key"]
        path = self.directory / f"{key}.json"
        return write_durably(path, json.dumps(entry))

    def remove(self, key: str) -> None:
        try:
            (self.directory / f"{key}.json").unlink()
        except FileNotFoundError:
            pass

    def pending(self) -> list[dict]:
        """Entries oldest first."""
        entries = []
        for p in self.directory.glob("*.json"):
            try:
                entries.append(json.loads(p.read_text()))
            except (OSError, ValueError):
                continue  # a torn write never got renamed into place, so this is not expected
        entries.sort(key=lambda e: (e.get("spooled_at", ""), e["capture_key"]))
        return entries

    def __len__(self) -> int:
        return sum(1 for _ in self.directory.glob("*.json"))


def utc_text(t: datetime) -> str:
    return t.astimezone(timezone.utc).isoformat().replace("+00:00", "Z")


def write_capture_bytes(files: dict[str, bytes], directory: Path, key: str) -> Path:
    """Store an uploaded capture byte for byte: ``files`` maps a suffix (".cfg", ".dat" or
    ".cff") to its bytes. Each file is written under a temporary name, fsynced and renamed, then
    the folder is fsynced. Returns the main file (the .cfg or the .cff)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    for suffix, data in files.items():
        write_durably(directory / f"{key}{suffix}", data, sync_dir=False)
    fsync_dir(directory)
    return directory / f"{key}{'.cff' if '.cff' in files else '.cfg'}"
