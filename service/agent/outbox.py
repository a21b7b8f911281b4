"""The edge agent's outbox: captures waiting to be forwarded, durable, in order, bounded in size.

The acquisition pipeline writes each capture's COMTRADE files (fsynced) under ``captures/``;
``put`` then journals it as ``outbox/<seq>.json`` (fsynced, renamed into place) with its
content hash, the idempotency key the central server deduplicates on. ``sent`` deletes the
files, then the entry. A crash between the two leaves an entry whose files are gone: it was
sent, and is dropped at start. A crash before ``put`` leaves files without an entry: they are
adopted at start. Either way nothing is lost, and a capture sent twice is stored once.

The outbox is bounded by ``max_bytes`` of capture files. When a new capture would pass the
bound it is refused (the oldest, unsent ones are kept), its files are deleted, an error is
logged and ``dropped`` counts it; ``full`` stays true until there is room again.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import threading
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from service.durable import fsync_dir, write_durably
from service.storage.spool import capture_digest

log = logging.getLogger("hvcb.agent.outbox")

SIDE_FILES = (".dat", ".hdr")


def capture_paths(cfg: Path) -> list[Path]:
    """The capture's files that exist: the .cfg, its .dat and (when written) its .hdr."""
    cfg = Path(cfg)
    return [p for p in [cfg] + [cfg.with_suffix(s) for s in SIDE_FILES] if p.exists()]


@dataclass(frozen=True)
class OutboxEntry:
    seq: int
    key: str            # content hash: the idempotency key
    breaker: str        # breaker name
    operation: str      # open | close
    cfg: str            # path of the .cfg (the .dat beside it)
    size: int           # bytes of the capture files
    captured_at: str    # UTC ISO-8601 of the capture's first sample

    @property
    def captured(self) -> datetime:
        return datetime.fromisoformat(self.captured_at)


class Outbox:
    """Durable FIFO of captures to forward (thread-safe)."""

    def __init__(self, directory: str | Path, capture_dir: str | Path, *, max_bytes: int):
        self.directory = Path(directory)
        self.rejected_dir = self.directory / "rejected"
        self.capture_dir = Path(capture_dir)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.capture_dir.mkdir(parents=True, exist_ok=True)
        self.max_bytes = int(max_bytes)
        self.dropped = 0
        self.rejected = 0
        self.sent_count = 0
        self.full = False
        self._lock = threading.Lock()
        self._entries: dict[int, OutboxEntry] = {}
        self._bytes = 0
        self._next_seq = 1
        self.changed = threading.Event()
        self._load()

    # -- start-up ------------------------------------------------------------------------------
    def _load(self) -> None:
        known: set[str] = set()
        for p in sorted(self.directory.glob("*.json")):
            try:
                entry = OutboxEntry(**json.loads(p.read_text()))
            except (OSError, ValueError, TypeError):
                log.error("outbox entry %s is unreadable; moved aside", p.name)
                self._set_aside(p)
                continue
            if not Path(entry.cfg).exists() or not Path(entry.cfg).with_suffix(".dat").exists():
                p.unlink(missing_ok=True)  # its files were deleted after it was sent
                continue
            self._entries[entry.seq] = entry
            self._bytes += entry.size
            known.add(str(Path(entry.cfg).resolve()))
            self._next_seq = max(self._next_seq, entry.seq + 1)
        # Captures written but not journalled (a crash between the two): adopt them, in file order.
        orphans = [c for c in sorted(self.capture_dir.rglob("*.cfg"), key=lambda c: (c.stat().st_mtime_ns, c.name))
                   if str(c.resolve()) not in known and c.with_suffix(".dat").exists()
                   and self.rejected_dir not in c.parents]
        for cfg in orphans:
            breaker, operation = _identify(cfg, self.capture_dir)
            captured = datetime.fromtimestamp(cfg.stat().st_mtime, timezone.utc)
            log.warning("adopting capture %s written before a crash", cfg.name)
            self.put(cfg, breaker=breaker, operation=operation, captured_at=captured)

    def _set_aside(self, p: Path) -> None:
        self.rejected_dir.mkdir(parents=True, exist_ok=True)
        os.replace(p, self.rejected_dir / p.name)

    # -- queue ---------------------------------------------------------------------------------
    def put(self, cfg: str | Path, *, breaker: str, operation: str, captured_at: datetime) -> OutboxEntry | None:
        """Journal a durable capture; None when the outbox is full (the capture is refused)."""
        cfg = Path(cfg).resolve()
        files = capture_paths(cfg)
        size = sum(p.stat().st_size for p in files)
        key = capture_digest([cfg, cfg.with_suffix(".dat")])
        with self._lock:
            if self._bytes + size > self.max_bytes:
                self.dropped += 1
                if not self.full:
                    log.error("ALARM: the outbox is full (%d captures, %d of %d bytes): new captures are refused "
                              "until the central server takes the spooled ones", len(self._entries), self._bytes,
                              self.max_bytes)
                self.full = True
                log.error("capture %s refused: the outbox is full (%d refused so far)", cfg.name, self.dropped)
                for p in files:
                    p.unlink(missing_ok=True)
                return None
            entry = OutboxEntry(self._next_seq, key, breaker, operation, str(cfg), size,
                                captured_at.astimezone(timezone.utc).isoformat())
            self._next_seq += 1
            path = self.directory / f"{entry.seq:012d}.json"
            write_durably(path, json.dumps(entry.__dict__))
            self._entries[entry.seq] = entry
            self._bytes += size
        self.changed.set()
        return entry

    def oldest(self) -> OutboxEntry | None:
        with self._lock:
            return self._entries[min(self._entries)] if self._entries else None

    def sent(self, entry: OutboxEntry) -> None:
        """The central server holds ``entry``: delete its files, then its journal entry."""
        for p in capture_paths(Path(entry.cfg)):
            p.unlink(missing_ok=True)
        self._forget(entry)
        with self._lock:
            self.sent_count += 1

    def reject(self, entry: OutboxEntry, reason: str) -> None:
        """The central server refused ``entry`` for good: keep its files aside, go on with the next."""
        self.rejected_dir.mkdir(parents=True, exist_ok=True)
        for p in capture_paths(Path(entry.cfg)):
            shutil.move(str(p), self.rejected_dir / p.name)
        (self.rejected_dir / f"{Path(entry.cfg).stem}.reason.txt").write_text(reason + "\n")
        self._forget(entry)
        with self._lock:
            self.rejected += 1
        log.error("capture %s rejected by the central server (kept in %s): %s", Path(entry.cfg).name,
                  self.rejected_dir, reason)

    def _forget(self, entry: OutboxEntry) -> None:
        (self.directory / f"{entry.seq:012d}.json").unlink(missing_ok=True)
        fsync_dir(self.directory)
        with self._lock:
            if self._entries.pop(entry.seq, None) is not None:
                self._bytes -= entry.size
            if self.full and self._bytes < self.max_bytes:
                self.full = False
                log.warning("the outbox has room again (%d of %d bytes)", self._bytes, self.max_bytes)

    # -- figures -------------------------------------------------------------------------------
    def __len__(self) -> int:
        with self._lock:
            return len(self._entries)

    @property
    def bytes(self) -> int:
        with self._lock:
            return self._bytes

    def oldest_age_s(self, now: datetime | None = None) -> float:
        """Age of the oldest unsent capture [s]; 0 when the outbox is empty."""
        entry = self.oldest()
        if entry is None:
            return 0.0
        now = now or datetime.now(timezone.utc)
        return max(0.0, (now - entry.captured).total_seconds())


def _identify(cfg: Path, capture_dir: Path) -> tuple[str, str]:
    """(breaker, operation) of a capture file written by the pipeline: ``<breaker>/op-...-<operation>.cfg``."""
    rel = cfg.resolve().relative_to(capture_dir.resolve())
    breaker = rel.parts[0] if len(rel.parts) > 1 else ""
    operation = cfg.stem.rsplit("-", 1)[-1]
    return breaker, operation if operation in ("open", "close") else ""
