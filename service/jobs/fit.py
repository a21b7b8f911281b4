"""The fit job and what follows it: capture file → fit → result row → drift alarms.

``run_fit_job`` runs in a worker process (local pool or Celery). It is idempotent: keyed by
the operation id, it claims the fit row, and the result is stored by a conditional update that
only one attempt can win, so a job run twice lands its result exactly once.
"""

from __future__ import annotations

import importlib
import inspect
import logging
import os
import socket
import time
from dataclasses import asdict, dataclass
from datetime import datetime

import numpy as np
from sqlalchemy import select

from service.storage import crud
from service.storage.db import cached_engine, session_factory
from service.storage.models import AlarmRow, BreakerRow, DriftStateRow, FitRow, OperationRow, utcnow
from service.storage.spool import capture_digest, capture_files

log = logging.getLogger("hvcb.jobs")


@dataclass(frozen=True)
class JobOptions:
    """What a worker needs to run a fit job; picklable, built from the settings."""

    database_url: str
    fit_function: str = "service.estimation:fit_capture"
    fit_seed: int = 1
    max_attempts: int = 3
    alarms: dict | None = None

    @classmethod
    def from_settings(cls, settings) -> "JobOptions":
        return cls(database_url=settings.sqlalchemy_url, fit_function=settings.fit_function,
                   fit_seed=settings.fit_seed, max_attempts=settings.max_attempts,
                   alarms=dict(settings.alarms))

    def to_dict(self) -> dict:
        return asdict(self)


def _resolve(dotted: str):
    module, _, name = dotted.partition(":")
    return getattr(importlib.import_module(module), name)


def _worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def run_fit_job(operation_id: int, options: JobOptions | dict) -> dict:
    """Fit one operation's capture and store the result (or the reason it failed).

    Returns ``{"operation_id", "status", "landed", "runtime_s"}``; ``status`` is ``skipped``
    when another attempt already finished the job.
    """
    if isinstance(options, dict):
        options = JobOptions(**options)
    Session = session_factory(cached_engine(options.database_url))
    with Session() as session, session.begin():
        fit = crud.claim_fit(session, operation_id=operation_id, worker=_worker_name())
        if fit is None:
            return {"operation_id": operation_id, "status": "skipped", "landed": False, "runtime_s": 0.0}
        if fit.attempts > options.max_attempts:
            crud.store_fit_failure(session, operation_id=operation_id,
                                   reason=f"the fit was started {fit.attempts - 1} times and its worker "
                                          f"stopped each time (crash or out of memory); giving up")
            return {"operation_id": operation_id, "status": "failed", "landed": True, "runtime_s": 0.0}
        op = session.get(OperationRow, operation_id)
        breaker_row = session.get(BreakerRow, op.breaker_id)
        dc, dc_source = None, None
        breaker = crud.breaker_model(breaker_row)
        if op.kind == "close":
            opening = crud.latest_opening_fit(session, breaker_id=op.breaker_id, before=op.occurred_at)
            if opening is not None:
                dc, dc_source = float(opening.parameters["AO"]), f"opening fit of operation {opening.operation_id}"
            else:
                dc, dc_source = float(breaker.design_parameters()["DC"]), "breaker file design value"
        previous = crud.latest_good_fit(session, breaker_id=op.breaker_id, kind=op.kind,
                                        before=op.occurred_at, exclude_operation=operation_id)
        previous = (previous.operation_id, previous.result) if previous is not None else None
        capture_path, expected_sha = op.capture_path, op.capture_sha256
        kind = op.kind
    t0 = time.perf_counter()
    try:
        # Built outside the claim's transaction: the first import of the estimator is slow.
        prior = warm_prior(breaker, kind, previous)
        result_dict, curve = _fit(capture_path, expected_sha, breaker, kind, dc, options, prior)
        if dc is not None:
            result_dict["dc_used"], result_dict["dc_source"] = dc, dc_source
        failure = None
    except Exception as exc:  # every failure is stored with its reason; the queue moves on
        failure = failure_reason(exc)
    runtime = time.perf_counter() - t0
    with Session() as session, session.begin():
        if failure is not None:
            landed = crud.store_fit_failure(session, operation_id=operation_id, reason=failure)
            return {"operation_id": operation_id, "status": "failed", "landed": landed, "runtime_s": runtime}
        # The breaker row is locked before the parameter rows are inserted (their foreign key
        # share-locks it): the other way round two workers deadlock in update_drift (PostgreSQL).
        session.execute(select(BreakerRow.id).where(BreakerRow.id == breaker_row.id).with_for_update())
        landed = crud.store_fit_result(session, operation_id=operation_id, result=result_dict, curve=curve)
        events = update_drift(session, breaker_id=breaker_row.id, options=options, prognoses=False) if landed else []
    if landed:  # the fit and its alarms are visible; the prognosis follows in its own transaction
        refresh_prognoses(Session, breaker_id=breaker_row.id, options=options, events=events)
    return {"operation_id": operation_id, "status": "done", "landed": landed, "runtime_s": runtime}


def failure_reason(exc: Exception) -> str:
    """The reason a job failed, in words an engineer understands."""
    from drivers.capture import CaptureError

    from service.errors import in_words

    text = in_words(exc)
    if isinstance(exc, CaptureError):
        return f"capture unusable: {text}"
    if type(exc).__name__ == "FitError":
        return str(exc) or text
    if isinstance(exc, (ImportError, AttributeError)) and "estimation" in text:
        return f"the estimator is not available: {text}"
    log.error("unexpected failure of a job: %s", text, exc_info=exc)  # the traceback, for developers
    return f"unexpected failure: {text}"


def warm_prior(breaker, kind: str, previous: tuple | None):
    """The warm start of a fit: the breaker's previous good fit ``(operation id, result dict)``
    of that kind when usable, else the breaker file's design values."""
    from service.estimation.warm_start import prior_from_design, prior_from_fit

    if previous is not None and previous[1]:
        prior = prior_from_fit(previous[1], f"the fit of operation {previous[0]}")
        if prior is not None:
            return prior
    return prior_from_design(breaker, kind)


def _accepts_prior(fit_function) -> bool:
    try:
        return "prior" in inspect.signature(fit_function).parameters
    except (TypeError, ValueError):
        return False


def _fit(capture_path: str, expected_sha: str, breaker, kind: str, dc, options: JobOptions,
         prior=None):
    from drivers.capture import CaptureError
    from service.acquisition.capture_file import read_stored_capture

    files = capture_files(capture_path)
    missing = [str(p) for p in files if not p.exists()]
    if missing:
        raise CaptureError(f"capture file missing: {', '.join(missing)}")
    if capture_digest(files) != expected_sha:
        raise CaptureError("capture file checksum does not match the one recorded at capture time "
                           "(file changed or corrupted on disk)")
    capture = read_stored_capture(capture_path, breaker)
    fit_capture = _resolve(options.fit_function)
    extra = {"prior": prior} if prior is not None and _accepts_prior(fit_capture) else {}
    result = fit_capture(capture, breaker, kind, dc=dc, seed=options.fit_seed, **extra)
    out = result.to_dict() if hasattr(result, "to_dict") else dict(result)
    # No curve is stored: it is rebuilt from the parameters when shown (service.storage.fit_curve),
    # which keeps the database at a few kB per operation.
    return _jsonable(out), None


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    if isinstance(obj, datetime):
        return obj.isoformat()
    return obj


# -- drift alarms ------------------------------------------------------------------------------
def _drift_state(session, breaker_id: int, parameter: str, settings):
    from service.alarms.drift import DriftState

    row = session.get(DriftStateRow, (breaker_id, parameter))
    if row is None or not row.state:
        return row, DriftState.new(parameter, settings)
    return row, DriftState.from_dict(row.state)


def _save_state(session, row, breaker_id: int, state) -> None:
    if row is None:
        row = DriftStateRow(breaker_id=breaker_id, parameter=state.parameter)
        session.add(row)
    row.state = state.to_dict()
    row.updated_at = utcnow()


def refresh_prognoses(Session, *, breaker_id: int, options: JobOptions, events: list) -> None:
    """Refresh the breaker's stored prognoses that are due (``service.jobs.prognosis.refresh_due``),
    after its fit committed: a failure here leaves the fit and its alarms stored, and the next
    fit finds the prognosis still due."""
    from service.alarms.settings import DriftSettings
    from service.jobs.prognosis import store_prognoses

    settings = DriftSettings.from_mapping(options.alarms or {})
    try:
        with Session() as session, session.begin():
            session.execute(select(BreakerRow.id).where(BreakerRow.id == breaker_id).with_for_update())
            store_prognoses(session, breaker_id=breaker_id, settings=settings,
                            force=frozenset(ev.parameter for ev in events))
    except Exception as exc:  # the fit stands; say why its prognosis did not follow
        from service.errors import in_words

        log.error("the prognosis of breaker %s was not refreshed: %s", breaker_id, in_words(exc), exc_info=exc)


def update_drift(session, *, breaker_id: int, options: JobOptions | None = None, settings=None,
                 prognoses: bool = True) -> list:
    """Feed the breaker's new good fits to the drift detector and store the alarm events; with
    ``prognoses``, refresh the stored prognoses that are due in the same transaction.

    Runs under a lock on the breaker row (PostgreSQL) or the database write lock (SQLite), so
    two workers finishing fits of one breaker at once cannot double-count. A fit that finishes
    after a newer one of the same breaker was already fed is not fed (the detector needs
    operation order); with one worker per breaker this does not happen.
    """
    from service.alarms import drift
    from service.alarms.settings import DriftSettings

    settings = settings or DriftSettings.from_mapping((options.alarms if options else None) or {})
    from service.storage.crud_alarms import operation_temperatures

    session.execute(select(BreakerRow.id).where(BreakerRow.id == breaker_id).with_for_update())
    breaker = session.get(BreakerRow, breaker_id)
    if breaker.out_of_service_since is not None:
        return []  # maintenance: nothing is watched; the baseline is reset at its end
    all_events = []
    for parameter in settings.watched:
        row, state = _drift_state(session, breaker_id, parameter, settings)
        since = state.last_time or breaker.baseline_reset_at
        from service.storage.crud_vibration import WATCHABLE, characteristic_history

        if parameter in WATCHABLE:  # the vibration's latch time, buffer ratio: in the characteristics, not fitted
            history = characteristic_history(session, breaker_id=breaker_id, name=parameter, since=since)
        else:
            history = crud.good_parameter_history(session, breaker_id=breaker_id, name=parameter, since=since)
        temps = operation_temperatures(session, {pv.operation_id for pv in history})
        for pv in history:
            if state.last_time is not None and (pv.occurred_at, pv.operation_id) <= (state.last_time, state.last_operation_id or 0):
                continue
            if breaker.baseline_reset_at is not None and pv.occurred_at < breaker.baseline_reset_at:
                continue  # an operation from before the reset (e.g. during maintenance)
            obs = drift.FitObservation(operation_id=pv.operation_id, time=pv.occurred_at, value=pv.value,
                                       ci95=(pv.ci_low, pv.ci_high) if pv.ci_low is not None and pv.ci_high is not None else None,
                                       temperature=temps.get(pv.operation_id))
            state, events = drift.update(state, obs, settings)
            for ev in events:
                apply_alarm_event(session, breaker_id=breaker_id, event=ev)
            all_events.extend(events)
        _save_state(session, row, breaker_id, state)
    session.flush()
    if prognoses:
        from service.jobs.prognosis import store_prognoses

        store_prognoses(session, breaker_id=breaker_id, settings=settings,
                        force=frozenset(ev.parameter for ev in all_events))
        session.flush()
    return all_events


def apply_alarm_event(session, *, breaker_id: int, event) -> AlarmRow | None:
    """Store one ``AlarmEvent`` of the drift detector in the alarms table."""
    active = crud.active_alarm(session, breaker_id=breaker_id, parameter=event.parameter)
    now = utcnow()
    if event.kind == "raised":
        from service.storage.crud_alarms import first_out_now

        alarm = AlarmRow(breaker_id=breaker_id, parameter=event.parameter, level=event.level, state="raised",
                         first_out=first_out_now(session, breaker_id=breaker_id),
                         episode=event.episode, message=_message(event), evidence=_jsonable(event.evidence),
                         operation_id=event.operation_id if isinstance(event.operation_id, int) else None,
                         raised_at=now, updated_at=now)
        session.add(alarm)
        session.flush()
        return alarm
    if active is None:
        return None
    if event.kind == "escalated":
        from service.alarms.lifecycle import Action
        from service.storage.crud_alarms import add_action, shelved_now

        if shelved_now(active, now):  # a shelve was for the lesser level: the escalation breaks through
            active.shelved_until = now
            add_action(session, breaker_id=breaker_id, alarm_id=active.id,
                       action=Action("unshelve", "hvcb", now, f"escalated to {event.level}", None, active.id))
        active.level, active.state = event.level, "raised"
        active.acknowledged_at = active.acknowledged_by = active.ack_comment = None
        active.evidence, active.message = _jsonable(event.evidence), _message(event)
        active.updated_at = now
    elif event.kind == "cleared":
        active.state, active.cleared_at, active.updated_at = "cleared", now, now
        active.evidence = {**(active.evidence or {}), "cleared": {"reason": event.reason,
                                                                  "operation_id": event.operation_id}}
    session.flush()
    return active


def _message(event) -> str:
    from service.display import parameter_label, signed_change
    from service.findings import likely_cause

    ev = event.evidence or {}
    direction = ev.get("drift_direction", "")
    change = (ev.get("current") or {}).get("change_rel")
    pct = f" ({signed_change(change)} from baseline)" if isinstance(change, (int, float)) else ""
    return (f"{event.level.upper()}: {parameter_label(event.parameter)} {direction}{pct}; "
            f"likely {likely_cause(event.parameter, direction)}")


def acknowledge_drift(session, *, alarm: AlarmRow, by: str, settings) -> None:
    """Keep the detector's state in step with an acknowledgement made through the API."""
    from service.alarms import actions

    row, state = _drift_state(session, alarm.breaker_id, alarm.parameter, settings)
    if row is not None and state.active and state.episode == alarm.episode:
        state, _ = actions.acknowledge(state, by=by, time=utcnow())
        _save_state(session, row, alarm.breaker_id, state)


def reset_baseline(session, *, breaker_id: int, by: str, settings) -> int:
    """Admin: the next good fits form a new baseline; active alarms of the breaker are cleared."""
    from service.alarms import actions

    session.execute(select(BreakerRow.id).where(BreakerRow.id == breaker_id).with_for_update())
    now = utcnow()
    cleared = 0
    for parameter in settings.watched:
        row, state = _drift_state(session, breaker_id, parameter, settings)
        state, events = actions.reset_baseline(state, by=by, time=now)
        for ev in events:
            if apply_alarm_event(session, breaker_id=breaker_id, event=ev) is not None:
                cleared += 1
        _save_state(session, row, breaker_id, state)
    breaker = session.get(BreakerRow, breaker_id)
    breaker.baseline_reset_at = now
    for alarm in crud.list_alarms(session, state="active", breaker_id=breaker_id):
        alarm.state, alarm.cleared_at, alarm.updated_at = "cleared", now, now
    session.flush()
    return cleared


def drift_status(session, *, breaker_id: int, settings) -> str:
    from service.alarms import actions
    from service.storage.crud_alarms import shelved_parameters

    states = [_drift_state(session, breaker_id, p, settings)[1] for p in settings.watched]
    return actions.health_status(states, shelved_parameters(session, breaker_id=breaker_id, now=utcnow()))


def fit_row_summary(fit: FitRow | None) -> dict | None:
    if fit is None:
        return None
    return {"status": fit.status, "attempts": fit.attempts}
