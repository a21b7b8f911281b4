"""Retention of raw capture files: what may be pruned, the preview kept instead, and the schedule.

Kept forever: operation rows, fits, parameter values, alarms, and the raw captures named by an
alarm's evidence, by a drift detector's baseline (or the fits collected for it, or a CUSUM run
that may yet become an alarm's evidence), and by a fit or diagnosis still to run. Any other raw
capture is pruned when older than ``max_age_days`` or not among the newest ``max_per_breaker``
unprotected captures of its breaker. A pruned capture leaves a ``capture_previews`` row: min/max
buckets of each channel, enough to draw the curve, a few kB instead of ~100 kB.

The preview row is committed before the files are removed, so a crash in between leaves the
files to be removed by the next run, never an operation with neither.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
from sqlalchemy import select

from service.decimation import minmax_indices

from .models import (AlarmRow, BreakerRow, CapturePreviewRow, DiagnosisRow, DriftStateRow, FitRow,
                     OperationRow, utcnow)
from .spool import capture_files

log = logging.getLogger("hvcb.retention")

# Keys of alarm evidence and drift states whose values are operation ids (or lists of them).
_ID_KEYS = {"operation_id", "operation_ids", "excluded_operation_ids", "run_rising", "run_falling",
            "last_operation_id"}


# -- what is referenced ------------------------------------------------------------------------
def _ids_in(obj, out: set[int]) -> None:
    """Collect operation ids from a JSON value: under the keys of ``_ID_KEYS``, the first item of
    each ``collected`` pair and of ``held``, at any depth."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            if k in _ID_KEYS:
                for x in (v if isinstance(v, (list, tuple)) else [v]):
                    if isinstance(x, int) and not isinstance(x, bool):
                        out.add(x)
            elif k == "collected" and isinstance(v, (list, tuple)):
                out.update(p[0] for p in v if isinstance(p, (list, tuple)) and p and isinstance(p[0], int))
            elif k == "held" and isinstance(v, (list, tuple)) and v and isinstance(v[0], int):
                out.add(v[0])
            else:
                _ids_in(v, out)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            _ids_in(v, out)


def protected_operations(session) -> dict[int, str]:
    """Operation id -> why its raw capture is kept whatever its age."""
    out: dict[int, str] = {}

    def mark(ids, why):
        for i in ids:
            out.setdefault(int(i), why)

    for op_id, evidence in session.execute(select(AlarmRow.operation_id, AlarmRow.evidence)):
        ids: set[int] = set()
        _ids_in(evidence or {}, ids)
        if op_id is not None:
            ids.add(op_id)
        mark(ids, "alarm evidence")
    for (state,) in session.execute(select(DriftStateRow.state)):
        ids = set()
        _ids_in((state or {}).get("baseline") or {}, ids)
        mark(ids, "baseline")
        ids = set()
        _ids_in({k: v for k, v in (state or {}).items() if k != "baseline"}, ids)
        mark(ids, "baseline or drift in progress")
    mark(session.scalars(select(FitRow.operation_id).where(FitRow.status.in_(("queued", "running")))),
         "fit pending")
    mark(session.scalars(select(DiagnosisRow.operation_id).where(DiagnosisRow.status.in_(("queued", "running")))),
         "diagnosis pending")
    from .models import BreakerDiagnosisRow

    for (ids,) in session.execute(select(BreakerDiagnosisRow.operation_ids)
                                  .where(BreakerDiagnosisRow.status.in_(("queued", "running")))):
        mark(ids or [], "breaker diagnosis pending")
    return out


# -- the plan ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Candidate:
    operation_id: int
    breaker_id: int
    capture_path: str
    files: tuple[Path, ...]
    bytes: int
    reason: str  # "age" | "count" | "unfinished" (preview stored by an interrupted run)
    has_preview: bool


@dataclass
class PrunePlan:
    candidates: list[Candidate] = field(default_factory=list)
    protected: dict[int, str] = field(default_factory=dict)
    skipped: list[tuple[int, str]] = field(default_factory=list)  # (operation id, why not prunable)

    @property
    def bytes(self) -> int:
        return sum(c.bytes for c in self.candidates)


def raw_files(path: str | Path) -> list[Path]:
    """Every file of a raw capture: the main file(s) and the COMTRADE header/info beside them."""
    files = list(capture_files(Path(path)))
    if Path(path).suffix.lower() == ".cfg":
        files += [Path(path).with_suffix(s) for s in (".hdr", ".inf")]
    return files


def _size(files) -> int:
    total = 0
    for p in files:
        try:
            total += p.stat().st_size
        except OSError:
            pass
    return total


def _inside(path: Path, root: Path) -> bool:
    try:
        path.resolve().relative_to(root.resolve())
        return True
    except ValueError:
        return False


def plan_prune(session, *, policy, capture_dir: Path, now: datetime | None = None) -> PrunePlan:
    """Which raw captures the policy removes now. ``policy``: ``RetentionSettings``."""
    now = now or utcnow()
    plan = PrunePlan(protected=protected_operations(session))
    previews = set(session.scalars(select(CapturePreviewRow.operation_id)))
    rows = session.execute(select(OperationRow.id, OperationRow.breaker_id, OperationRow.occurred_at,
                                  OperationRow.capture_path)
                           .order_by(OperationRow.breaker_id, OperationRow.occurred_at.desc(),
                                     OperationRow.id.desc())).all()
    cutoff = now - timedelta(days=policy.max_age_days) if policy.max_age_days is not None else None
    rank: dict[int, int] = {}
    for op_id, breaker_id, occurred_at, path in rows:
        if occurred_at.tzinfo is None:
            occurred_at = occurred_at.replace(tzinfo=timezone.utc)
        present = [p for p in raw_files(path) if p.exists()]
        if op_id in previews:
            if present and op_id not in plan.protected:
                plan.candidates.append(Candidate(op_id, breaker_id, path, tuple(present), _size(present),
                                                 "unfinished", True))
            continue
        if op_id in plan.protected:
            continue
        n = rank.get(breaker_id, 0)
        rank[breaker_id] = n + 1
        reason = None
        if cutoff is not None and occurred_at < cutoff:
            reason = "age"
        elif policy.max_per_breaker is not None and n >= policy.max_per_breaker:
            reason = "count"
        if reason is None:
            continue
        if not present:
            plan.skipped.append((op_id, "raw capture already missing"))
            continue
        if not all(_inside(p, capture_dir) for p in present):
            plan.skipped.append((op_id, f"{path} is outside the capture directory {capture_dir}; left alone"))
            continue
        plan.candidates.append(Candidate(op_id, breaker_id, path, tuple(present), _size(present), reason, False))
    return plan


# -- the preview -------------------------------------------------------------------------------
def capture_preview(t, travel, vibration=None, *, sample_rate: float, buckets: int = 100) -> dict:
    """Decimated preview of a capture: samples at each bucket's minimum and maximum of every
    channel, so the travel's shape and every vibration shock stay visible.

    t [s], travel [rad], vibration [g] or None; returns {"t", "travel", "vibration",
    "sample_rate" [Hz], "n_samples", "buckets"} with plain lists (JSON)."""
    t, travel = np.asarray(t, float), np.asarray(travel, float)
    idx = minmax_indices(travel, buckets)
    if vibration is not None:
        vibration = np.asarray(vibration, float)
        idx = np.union1d(idx, minmax_indices(vibration, buckets))
    return {"t": np.round(t[idx], 7).tolist(), "travel": np.round(travel[idx], 6).tolist(),
            "vibration": None if vibration is None else np.round(vibration[idx], 4).tolist(),
            "sample_rate": float(sample_rate), "n_samples": int(travel.size), "buckets": int(buckets)}


def _preview_from_file(path: str, breaker, buckets: int) -> dict:
    from drivers.capture import CaptureError
    from service.acquisition.capture_file import read_stored_capture

    try:
        cap = read_stored_capture(path, breaker)
    except (CaptureError, OSError, ValueError) as exc:
        return {"t": [], "travel": [], "vibration": None, "unreadable": str(exc)}
    return capture_preview(cap.t, cap.travel, cap.vibration, sample_rate=cap.sample_rate, buckets=buckets)


# -- pruning -----------------------------------------------------------------------------------
@dataclass
class PruneReport:
    dry_run: bool
    captures: int
    bytes_freed: int
    protected: int
    skipped: list[tuple[int, str]]
    by_reason: dict[str, int]

    def summary(self) -> str:
        verb = "would remove" if self.dry_run else "removed"
        mb = self.bytes_freed / 1e6
        reasons = ", ".join(f"{n} by {r}" for r, n in sorted(self.by_reason.items())) or "none"
        return (f"{verb} {self.captures} raw capture(s) ({reasons}), "
                f"{'would free' if self.dry_run else 'freed'} {self.bytes_freed} bytes ({mb:.1f} MB); "
                f"{self.protected} capture(s) protected (alarm evidence, baselines, pending fits)")


def prune(Session, *, policy, capture_dir: Path, dry_run: bool = False, now: datetime | None = None,
          batch: int = 50, stop: threading.Event | None = None) -> PruneReport:
    """Apply the retention policy: store each pruned capture's preview, then remove its files."""
    from service.storage import crud

    with Session() as session:
        plan = plan_prune(session, policy=policy, capture_dir=capture_dir, now=now)
    by_reason: dict[str, int] = {}
    for c in plan.candidates:
        by_reason[c.reason] = by_reason.get(c.reason, 0) + 1
    report = PruneReport(dry_run, len(plan.candidates), plan.bytes, len(plan.protected), plan.skipped, by_reason)
    if dry_run or not plan.candidates:
        return report
    models: dict[int, object] = {}
    freed = done = 0
    for start in range(0, len(plan.candidates), batch):
        if stop is not None and stop.is_set():
            break
        chunk = plan.candidates[start:start + batch]
        with Session() as session, session.begin():
            # re-check under this transaction: a fit may have been queued or an alarm raised since
            protected = protected_operations(session)
            chunk = [c for c in chunk if c.operation_id not in protected]
            for c in chunk:
                if c.has_preview:
                    continue
                if c.breaker_id not in models:
                    models[c.breaker_id] = crud.breaker_model(session.get(BreakerRow, c.breaker_id))
                session.add(CapturePreviewRow(operation_id=c.operation_id, bytes_freed=c.bytes,
                                              preview=_preview_from_file(c.capture_path, models[c.breaker_id],
                                                                         policy.preview_buckets)))
        for c in chunk:
            for p in c.files:
                try:
                    p.unlink()
                except FileNotFoundError:
                    pass
            freed += c.bytes
            done += 1
    report.captures, report.bytes_freed = done, freed
    log.info("retention: %s", report.summary())
    return report


def get_preview(session, *, operation_id: int) -> CapturePreviewRow | None:
    return session.get(CapturePreviewRow, operation_id)


class RetentionSchedule:
    """Runs ``prune`` in a thread: first after ``min(interval, first_after_s)``, then every interval."""

    def __init__(self, settings, Session, *, first_after_s: float = 60.0):
        self.settings, self.Session = settings, Session
        self.first_after_s = first_after_s
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.last_report: PruneReport | None = None

    @property
    def enabled(self) -> bool:
        r = self.settings.retention
        return r.active and r.interval_s > 0

    def start(self) -> None:
        if not self.enabled:
            return
        self._thread = threading.Thread(target=self._loop, name="hvcb-retention", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=30)

    def _loop(self) -> None:
        interval = self.settings.retention.interval_s
        wait = min(interval, self.first_after_s)
        while not self._stop.wait(wait):
            try:
                self.last_report = prune(self.Session, policy=self.settings.retention,
                                         capture_dir=self.settings.capture_dir, stop=self._stop)
            except Exception:  # the next run tries again; the service carries on
                log.exception("retention: prune failed")
            wait = interval
