"""Breaker-level gap diagnosis (issue 20): the last N stored operations of one kind, diagnosed
together by ``service.diagnosis.diagnose`` in the worker pool, and the bounded queue in front of it.

Asking: :func:`queue_diagnosis` picks the operations, answers an identical earlier request with
its row, enforces the per-caller bound (finding D12 of issue 25) and stores the request before
anyone is told it is queued. Running: :func:`run_breaker_diagnosis_job` in a worker process.
"""

from __future__ import annotations

import json
import logging
import threading

from service.breaker_file import effect_strengths
from service.errors import UserError
from service.storage import crud, crud_diagnoses
from service.storage.db import cached_engine, session_factory
from service.storage.models import BreakerDiagnosisRow, BreakerRow, OperationRow
from service.storage.spool import capture_digest, capture_files

log = logging.getLogger("hvcb.diagnosis")

# How many operations one diagnosis takes together. Two is the least a joint fit can compare
# (hold-out leaves one out); twenty keeps one job near the speed target (10 captures in
# 60 s on two cores) scaled by two, so no single request holds the pool for minutes.
MIN_LAST, MAX_LAST = 2, 20

# Queued + running diagnoses a caller may have at once (finding D12 of issue 25). The pool runs
# one diagnosis at a time (each uses both cores), about a minute for 10 captures: a reader key may
# hold 2 (one running, one waiting), and all reader keys together 4, so readers can keep the pool
# busy for at most about 4 minutes ahead of everyone else. Operators and admins are trusted to ask
# for more (a bound against a runaway script, not a quota).
PER_KEY_BOUND = {"reader": 2, "operator": 5, "admin": 10}
ROLE_BOUND = {"reader": 4}
# Retry-After: about one diagnosis of 10 captures (the 60 s target).
RETRY_AFTER_S = 60


# Count-then-insert under one lock, so concurrent requests of one API process cannot both pass
# the bound (several API processes on one database may still overshoot it by one each).
_BOUND_LOCK = threading.Lock()


class QueueFull(UserError):
    """The caller already has as many diagnoses queued or running as its role allows."""

    def __init__(self, message: str, retry_after_s: int = RETRY_AFTER_S):
        super().__init__(message)
        self.retry_after_s = retry_after_s


class NothingToDiagnose(UserError):
    """No stored operation of that kind can be diagnosed."""


def queue_diagnosis(session, *, breaker: BreakerRow, kind: str, last: int, who) -> tuple[BreakerDiagnosisRow, bool]:
    """Queue the diagnosis of ``breaker``'s last ``last`` usable ``kind`` operations for ``who``
    (an API principal or a web user: ``key_id``, ``name``, ``role``).

    Returns ``(row, created)``: ``created`` is False when an identical request (same breaker,
    operation and operations) is queued, running or done, whose row is returned instead.
    Raises :class:`NothingToDiagnose` or :class:`QueueFull` with the reason in words. The caller
    submits the row to the runner when ``created``.
    """
    if kind not in ("open", "close"):
        raise UserError(f"operation must be 'open' or 'close', not {kind!r}")
    if not MIN_LAST <= last <= MAX_LAST:
        raise UserError(f"last must be between {MIN_LAST} and {MAX_LAST} operations, not {last}")
    ops, skipped = crud_diagnoses.select_operations(session, breaker_id=breaker.id, kind=kind, last=last)
    what = "opening" if kind == "open" else "closing"
    if not ops:
        left = f" ({len(skipped)} left out: {_reasons(skipped)})" if skipped else ""
        raise NothingToDiagnose(f"breaker {breaker.name!r} has no stored {what} that can be diagnosed{left}")
    ids = [op.id for op in ops]
    key = crud_diagnoses.selection_key(breaker_id=breaker.id, kind=kind, operation_ids=ids)
    existing = crud_diagnoses.find_active(session, key=key)
    if existing is not None:
        return existing, False
    role = who.role if who.role in PER_KEY_BOUND else "reader"
    with _BOUND_LOCK:
        session.rollback()  # count what is committed now, not what this session saw before the lock
        mine, theirs = crud_diagnoses.pending_counts(session, key_id=who.key_id, role=role)
        if mine >= PER_KEY_BOUND[role]:
            raise QueueFull(f"you already have {mine} breaker diagnoses queued or running, the most a {role} key "
                            f"may have at once ({PER_KEY_BOUND[role]}); ask again when one has finished")
        if role in ROLE_BOUND and theirs >= ROLE_BOUND[role]:
            raise QueueFull(f"{theirs} breaker diagnoses asked by {role} keys are queued or running, the most "
                            f"{role}s may have together ({ROLE_BOUND[role]}); ask again when one has finished")
        return crud_diagnoses.insert(session, breaker_id=breaker.id, kind=kind, last=last, operation_ids=ids,
                                     skipped=skipped, key=key, requested_by=who.name, key_id=who.key_id,
                                     role=role)


def _reasons(skipped: list[dict]) -> str:
    counts: dict[str, int] = {}
    for s in skipped:
        counts[s["reason"]] = counts.get(s["reason"], 0) + 1
    return "; ".join(f"{n} because {r}" for r, n in counts.items())


def summary(row: BreakerDiagnosisRow) -> str:
    """One sentence: how many operations were used and how many were left out, and why."""
    what = "opening" if row.operation == "open" else "closing"
    used = len(row.operation_ids or [])
    text = f"{used} stored {what}{'s' if used != 1 else ''} used of the last {row.last_n} asked for"
    if row.skipped:
        text += f"; {len(row.skipped)} newer left out ({_reasons(row.skipped)})"
    return text


def run_breaker_diagnosis_job(diagnosis_id: int, database_url: str) -> str:
    """Diagnose one queued breaker diagnosis and store its result or the reason it failed.

    Idempotent: a finished row is left alone (``skipped``); a row left ``running`` by a process
    that died is run again. Returns the final status.
    """
    from service import diagnosis

    Session = session_factory(cached_engine(database_url))
    with Session() as session, session.begin():
        row = crud_diagnoses.claim(session, diagnosis_id=diagnosis_id)
        if row is None:
            return "skipped"
        brow = session.get(BreakerRow, row.breaker_id)
        breaker = crud.breaker_model(brow)
        strengths = effect_strengths(brow.breaker_file, source=f"of breaker {brow.name!r}")
        kind = row.operation
        ops = [session.get(OperationRow, i) for i in row.operation_ids]
        jobs = [(op.id, op.capture_path, op.capture_sha256) for op in ops if op is not None]
        gone = [{"operation_id": i, "reason": "the operation was deleted"}
                for i, op in zip(row.operation_ids, ops) if op is None]
    result, reason = None, None
    try:
        captures, unreadable = _read(jobs, breaker)
        gone += unreadable
        if not captures:
            raise diagnosis.DiagnosisError("none of the selected captures can be read any more: "
                                           + "; ".join(f"operation {g['operation_id']}: {g['reason']}" for g in gone))
        out = diagnosis.diagnose([c for _, c in captures], breaker, kind, strengths=strengths)
        out["operation_ids"] = [i for i, _ in captures]
        result = json.loads(json.dumps(out, default=_plain, allow_nan=True), parse_constant=lambda _: None)
    except diagnosis.DiagnosisError as exc:
        reason = str(exc)
    except Exception as exc:  # stored in words; the traceback goes to the log
        log.exception("breaker diagnosis %s failed", diagnosis_id)
        reason = f"the diagnosis stopped on an internal error: {exc}" if str(exc) else \
            "the diagnosis stopped on an internal error (see the service log)"
    with Session() as session, session.begin():
        if gone:
            row = session.get(BreakerDiagnosisRow, diagnosis_id)
            if row is not None:
                row.skipped = list(row.skipped or []) + gone
        crud_diagnoses.finish(session, diagnosis_id=diagnosis_id, result=result, reason=reason)
    return "done" if reason is None else "failed"


def _read(jobs, breaker):
    """[(operation id, Capture)] of the files that are still there and unchanged, and the others
    as ``{"operation_id", "reason"}``."""
    from drivers.capture import CaptureError
    from service.acquisition.capture_file import read_capture

    out, bad = [], []
    for op_id, path, sha in jobs:
        files = capture_files(path)
        if any(not p.exists() for p in files):
            bad.append({"operation_id": op_id, "reason": "its capture file is missing"})
            continue
        if capture_digest(files) != sha:
            bad.append({"operation_id": op_id, "reason": "its capture file changed since it was recorded"})
            continue
        try:
            out.append((op_id, read_capture(path, travel_channel=breaker.channels.get("travel", "travel"),
                                            vibration_channel=breaker.channels.get("vibration", "vibration"))))
        except CaptureError as exc:
            bad.append({"operation_id": op_id, "reason": f"its capture is unreadable: {exc}"})
    return out, bad


def _plain(obj):
    """numpy scalars and arrays as JSON; anything else as its text."""
    if hasattr(obj, "tolist"):
        return obj.tolist()
    try:
        return float(obj)
    except (TypeError, ValueError):
        return str(obj)
