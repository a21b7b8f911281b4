"""The service's orchestration: capture (durable) → operation row → fit job.

``Monitor.ingest`` is what an acquisition pipeline's ``on_capture`` and the upload endpoint
call. The capture file and a spool entry are fsynced first; the operation row (with its queued
fit) is committed next; only then is the job submitted. When the database is unreachable the
spool entry stays and a background thread stores it after recovery. At start-up the spool is
drained and every fit left queued or running is re-queued.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from pathlib import Path

from sqlalchemy.exc import DBAPIError, IntegrityError, OperationalError

from drivers.capture import Capture, CaptureError
from service.errors import in_words
from service.storage import crud
from service.storage.spool import Spool, capture_digest, capture_files, write_capture_file

log = logging.getLogger("hvcb.monitor")


@dataclass(frozen=True)
class IngestResult:
    capture_key: str
    operation_id: int | None  # None: spooled, the database was unavailable
    spooled: bool
    more: tuple = ()  # the further operations of one uploaded record (IngestResult each)


def infer_operation(capture: Capture) -> str:
    """``open`` when the travel moves away from the closed position (0 rad), else ``close``."""
    n = max(1, capture.travel.size // 20)
    start, end = float(capture.travel[:n].mean()), float(capture.travel[-n:].mean())
    if abs(end - start) < 1e-3:
        raise CaptureError("the travel does not move: no operation in this capture")
    return "open" if end > start else "close"


CLOCK_SUSPECT = "clock suspect"


def clock_suspect(occurred: datetime, arrived: datetime, tolerance_s: float) -> bool:
    """True when a capture is dated more than ``tolerance_s`` after it arrived. A record cannot
    come from the future: beyond any plausible clock drift or time-zone slip (a day by default,
    more than the largest UTC offset of 14 h), its clock is wrong. Old dates are not suspect:
    recordings are uploaded long after the fact."""
    return (occurred - arrived).total_seconds() > tolerance_s


class Monitor:
    """Owns the spool, the executor and the recovery thread of one service process."""

    def __init__(self, settings, session_factory, executor, *, metrics=None):
        self.settings = settings
        self.Session = session_factory
        self.executor = executor
        self.metrics = metrics
        self.spool = Spool(settings.spool_dir)
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self._drain_lock = threading.Lock()
        self.db_ok = True
        self.clock_suspect: dict[int, int] = {}  # breaker id -> clock-suspect captures since start

    # -- lifecycle -----------------------------------------------------------------------------
    def start(self) -> None:
        self.executor.start()
        self.recover()
        self._thread = threading.Thread(target=self._spool_loop, name="hvcb-spool", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=10)
        # A local pool's running fits end now (Ctrl-C stops the service within seconds, not a
        # fit's time); recover() re-queues them at the next start. Others finish their job.
        self.executor.shutdown(wait=getattr(self.executor, "kind", None) != "local")

    def recover(self) -> int:
        """Store spooled captures, then re-queue fits left queued or running. Returns jobs queued."""
        self.drain_spool()
        try:
            with self.Session() as session:
                pending = crud.pending_operation_ids(session)
        except (OperationalError, DBAPIError) as exc:
            log.warning("database unavailable at start-up (%s); will retry", in_words(exc))
            self.db_ok = False
            return 0
        for op_id in pending:
            self.executor.submit(op_id)
        if pending:
            log.info("re-queued %d fit(s) left pending", len(pending))
        return len(pending)

    # -- ingest --------------------------------------------------------------------------------
    def ingest(self, capture: Capture, *, breaker_id: int, operation: str | None = None,
               source: str = "daq", capture_path: str | Path | None = None,
               capture_key: str | None = None) -> IngestResult:
        """Make ``capture`` durable, store its operation and queue its fit.

        ``capture_path``: the capture is already durable in this COMTRADE file (the acquisition
        pipeline wrote and fsynced it); it is referenced, not copied.
        ``capture_key``: the caller's idempotency key (an edge agent's content hash); an
        operation stored under it before is returned, never stored twice.
        """
        kind = operation or capture.meta.get("operation") or infer_operation(capture)
        if kind not in ("open", "close"):
            raise CaptureError(f"operation must be 'open' or 'close', got {kind!r}")
        key = capture_key or Spool.new_key()
        now = datetime.now(timezone.utc)
        occurred = capture.start_time or now
        if occurred.tzinfo is None:
            occurred = occurred.replace(tzinfo=timezone.utc)
        suspect = clock_suspect(occurred, now, getattr(self.settings, "clock_tolerance_s", 86400.0))
        flags = list(capture.flags)
        if suspect:
            flags.append(CLOCK_SUSPECT)
            self.clock_suspect[breaker_id] = self.clock_suspect.get(breaker_id, 0) + 1
            log.warning("breaker %s: a %s capture is dated %s, %.1f h after it arrived: stored, flagged "
                        "clock suspect and kept out of latest values, SCADA and the drift baseline%s",
                        breaker_id, source, occurred.isoformat(), (occurred - now).total_seconds() / 3600,
                        " (the DAQ's clock jumped: set it right)" if source == "daq" else "")
        directory = self.settings.capture_dir / now.strftime("%Y") / now.strftime("%m%d")
        if capture_path is not None:
            path = Path(capture_path)
            sha = capture_digest(capture_files(path))
        else:
            path, sha = write_capture_file(capture, directory, key)
        entry = {"capture_key": key, "breaker_id": breaker_id, "kind": kind,
                 "occurred_at": occurred.isoformat(), "source": source, "capture_path": str(path.resolve()),
                 "capture_sha256": sha, "flags": flags, "clock_suspect": suspect, "sample_rate": capture.sample_rate,
                 "n_samples": int(capture.travel.size), "spooled_at": now.isoformat(),
                 "temperature_c": capture.meta.get("temperature_c"),
                 "temperature_source": capture.meta.get("temperature_source")}
        self.spool.put(entry)
        if self.metrics is not None:
            self.metrics.captures.labels(source=source).inc()
        op_id = self._store(entry) if self.db_ok else None
        if op_id is None:
            self._wake.set()
        return IngestResult(key, op_id, op_id is None)

    def _store(self, entry: dict) -> int | None:
        """Commit one spool entry's operation and submit its job; None if the DB is unavailable."""
        try:
            with self.Session() as session, session.begin():
                op, created = crud.create_operation(
                    session, capture_key=entry["capture_key"], breaker_id=entry["breaker_id"], kind=entry["kind"],
                    occurred_at=datetime.fromisoformat(entry["occurred_at"]), source=entry["source"],
                    capture_path=entry["capture_path"], capture_sha256=entry["capture_sha256"],
                    flags=entry["flags"], sample_rate=entry["sample_rate"], n_samples=entry["n_samples"],
                    clock_suspect=entry.get("clock_suspect", False),
                    temperature_c=entry.get("temperature_c"), temperature_source=entry.get("temperature_source"))
                op_id = op.id
        except IntegrityError:  # stored concurrently by the spool thread: look it up
            with self.Session() as session:
                op = crud.get_operation_by_key(session, capture_key=entry["capture_key"])
                if op is None:
                    raise
                op_id = op.id
        except (OperationalError, DBAPIError) as exc:
            if self.db_ok:  # the driver's own words (e.g. "database is locked"), not a class name
                log.warning("database unavailable (%s); spooling captures until it is back", in_words(exc))
            self.db_ok = False
            return None
        if not self.db_ok:
            log.warning("database back; storing spooled captures")
        self.db_ok = True
        self.spool.remove(entry["capture_key"])
        self.executor.submit(op_id)
        return op_id

    def drain_spool(self) -> int:
        """Store every spooled capture that can be stored now; returns how many were stored."""
        stored = 0
        with self._drain_lock:
            for entry in self.spool.pending():
                if not Path(entry["capture_path"]).exists():
                    log.error("spooled capture %s has no file; dropping the entry", entry["capture_key"])
                    self.spool.remove(entry["capture_key"])
                    continue
                if self._store(entry) is None:
                    break
                stored += 1
        return stored

    def requeue_stale(self) -> int:
        """Queue again the fits left `running` longer than the lease (their worker is gone)."""
        cutoff = datetime.now(timezone.utc) - timedelta(seconds=self.settings.fit_lease_s)
        try:
            with self.Session() as session, session.begin():
                stale = crud.requeue_stale_fits(session, older_than=cutoff)
        except (OperationalError, DBAPIError):
            return 0  # the spool thread notices the outage; the next sweep tries again
        for op_id in stale:
            log.warning("fit of operation %d was running for over %.0f s: its worker is gone; queued again",
                        op_id, self.settings.fit_lease_s)
            self.executor.submit(op_id)
        return len(stale)

    def _spool_loop(self) -> None:
        # The stale-fit sweep needs no finer grain than a tenth of the lease.
        sweep_every, last_sweep = self.settings.fit_lease_s / 10.0, time.monotonic()
        while not self._stop.is_set():
            self._wake.wait(self.settings.spool_retry_s)
            self._wake.clear()
            if self._stop.is_set():
                return
            if time.monotonic() - last_sweep >= sweep_every:
                last_sweep = time.monotonic()
                self.requeue_stale()
            if len(self.spool):
                try:
                    self.drain_spool()
                except Exception:
                    log.exception("draining the spool failed")
