"""The prognosis of a breaker's limited parameters, from the database: the I/O side of
service.prognosis. The worker refreshes the stored one when it is due (``store_prognoses``,
after ``service.jobs.fit.update_drift``); the API and the pages compute it fresh
(``breaker_prognoses``)."""

from __future__ import annotations

from dataclasses import asdict
from datetime import datetime

from sqlalchemy import select

from service.prognosis import words
from service.storage import crud
from service.storage.crud_alarms import operation_temperatures
from service.storage.models import BreakerRow, DriftStateRow, PrognosisRow, utcnow

HOW_TO_ADD = ('add a [limits] table to the breaker file, e.g. DO = { min_change = -0.25 } '
              '(docs/breaker-file.md, "Maintenance limits")')


def limits_of(breaker: BreakerRow):
    """The breaker file's [limits] (an empty table when it has none or the file fails to parse)."""
    from service.breaker_file import BreakerFileError, parse_breaker_text
    from service.breaker_limits import Limits

    try:
        return parse_breaker_text(breaker.breaker_file, source=f"{breaker.name} (stored)").limits
    except BreakerFileError:
        return Limits()


# The prognosis reads at most the last HISTORY_FITS good fits of a parameter, so its cost per fit
# is bounded however long the breaker has run (the detector's own state is incremental). The
# window holds every basis the calibration bench draws (the longest: 250 healthy fits before the
# change point plus 375 after it, against PRE_FITS = 200 before it needed) and, at one opening a
# day, 2.7 years: the annual cycle of a breaker without temperature twice over. A longer trend's
# slope is known to its sd / sqrt(1000) already: older fits add nothing a planner would see.
HISTORY_FITS = 1000


def _restarted_at(session, breaker: BreakerRow, parameter: str) -> datetime | None:
    """The latest of the baseline reset and the last logged maintenance touching ``parameter``:
    the parameter's history starts there."""
    from service.storage.maintenance import restart_time

    since = [t for t in (breaker.baseline_reset_at, restart_time(session, breaker.id, parameter)) if t is not None]
    return max(since) if since else None


def _rows_after(session, breaker: BreakerRow, parameter: str, since: datetime | None):
    """The parameter's good fits at or after ``since`` (all since the restart when None), oldest first."""
    from service.storage.crud_vibration import WATCHABLE, characteristic_history

    if parameter in WATCHABLE:
        return characteristic_history(session, breaker_id=breaker.id, name=parameter, since=since)
    return crud.good_parameter_history(session, breaker_id=breaker.id, name=parameter, since=since)


def _observations(session, rows):
    from service.alarms import FitObservation

    temps = operation_temperatures(session, {r.operation_id for r in rows})
    return [FitObservation(operation_id=r.operation_id, time=r.occurred_at, value=r.value,
                           ci95=(r.ci_low, r.ci_high) if r.ci_low is not None and r.ci_high is not None else None,
                           temperature=temps.get(r.operation_id))
            for r in rows]


# The calibration's state (service/prognosis/calibration.py) lives in the stored prognosis's
# result under this key: scored on every fit (a query of the fits since the last scored one and
# a few microseconds each), carried into the next refresh, restarted with the history.
CALIBRATION = "calibration_state"


def calibration_key(session, breaker: BreakerRow, parameter: str) -> str:
    """The history the calibration belongs to: its start (a baseline reset or a logged repair)."""
    since = _restarted_at(session, breaker, parameter)
    return "reset" if since is None else _aware(since).isoformat()


def stored_calibration(session, *, breaker: BreakerRow, parameter: str, stored: PrognosisRow | None, state):
    """The parameter's calibration with every good fit since its last scored one scored
    (``calibration.score``): a fresh one after a reset or a logged repair."""
    from service.prognosis import calibration as cal_
    from service.prognosis import compensated

    key = calibration_key(session, breaker, parameter)
    cal = cal_.Calibration.from_dict((stored.result or {}).get(CALIBRATION) if stored is not None else None, key=key)
    if not cal.forecasts or cal.last_time is None or state is None or state.model is None:
        return cal
    t = datetime.fromisoformat(cal.last_time)
    rows = [r for r in _rows_after(session, breaker, parameter, t)
            if (_aware(r.occurred_at), r.operation_id) > (_aware(t), cal.last_id or 0)]
    if not rows:
        return cal
    obs = _observations(session, rows)
    y, w, _ = compensated(state, obs)
    sd = state.model.sd
    for o, y_i, w_i in zip(obs, y, w):
        cal = cal_.score(cal, float(y_i), sd / max(float(w_i), 1e-12) ** 0.5, o.operation_id, _aware(o.time).isoformat())
    return cal


def _after_prognosis(cal, p, last):
    """The calibration after prognosis ``p`` made on the fits up to ``last``: its forecast
    pending, and the pending crossings judged when the trend has passed its limit."""
    from service.prognosis import calibration as cal_

    if cal is None:
        return None
    if p.status == "crossed":
        cal = cal_.crossed(cal)
    if p.forecast and last is not None:
        q = p.operations_to_limit
        crossing = None if q is None or p.status != "ok" else (q.p05, q.p95)
        cal = cal_.issue(cal, p.forecast["ahead"], p.forecast["median"], p.forecast["lo"], p.forecast["hi"],
                         crossing, operation_id=last.operation_id, time=_aware(last.time).isoformat())
    return cal


def _history(session, breaker: BreakerRow, parameter: str):
    """The parameter's last ``HISTORY_FITS`` good fits since the baseline reset or the last
    logged maintenance touching it (service/storage/maintenance.py), oldest first: the tail of
    what the detector was fed."""
    from service.alarms import FitObservation
    from service.storage.crud_vibration import WATCHABLE, characteristic_history

    since = _restarted_at(session, breaker, parameter)
    if parameter in WATCHABLE:  # the vibration's latch time, buffer ratio: in the characteristics, not fitted
        rows = characteristic_history(session, breaker_id=breaker.id, name=parameter,
                                      since=since)[-HISTORY_FITS:]
    else:
        rows = crud.good_parameter_history(session, breaker_id=breaker.id, name=parameter,
                                           since=since, last=HISTORY_FITS)
    temps = operation_temperatures(session, {r.operation_id for r in rows})
    return [FitObservation(operation_id=r.operation_id, time=r.occurred_at, value=r.value,
                           ci95=(r.ci_low, r.ci_high) if r.ci_low is not None and r.ci_high is not None else None,
                           temperature=temps.get(r.operation_id))
            for r in rows]


def breaker_prognoses(session, *, breaker: BreakerRow, settings, horizon_years: float = 10.0) -> list:
    """``service.prognosis.Prognosis`` of each limited parameter, soonest median first."""
    settings = settings.for_breaker(breaker.name)  # its [alarms.breakers.NAME] overrides
    out = [parameter_prognosis(session, breaker=breaker, parameter=parameter, limit=limit, settings=settings,
                               horizon_years=horizon_years)[0]
           for parameter, limit in limits_of(breaker).items()]
    return sorted(out, key=soonest_key)


def parameter_prognosis(session, *, breaker: BreakerRow, parameter: str, limit, settings,
                        horizon_years: float = 10.0, stored: PrognosisRow | None = None,
                        calibration=None) -> tuple:
    """``(Prognosis, history, calibration)`` of one limited parameter: its prognosis, the fits
    it read, and the calibration it was read with (the stored one brought up to date, or
    ``calibration`` when given; None for a parameter that is not watched)."""
    from service.alarms import DriftState
    from service.prognosis import Prognosis, prognose

    if parameter not in settings.watched:
        return Prognosis(parameter, None, None, limit.describe(), status="no trend",
                         reason=f"{parameter} is not watched by the drift detector, which learns "
                                "its compensated baseline ([alarms] watched)"), [], None
    row = session.get(DriftStateRow, (breaker.id, parameter))
    state = DriftState.from_dict(row.state) if row is not None and row.state else DriftState.new(parameter, settings)
    history = _history(session, breaker, parameter)
    if calibration is None:
        if stored is None:
            stored = session.get(PrognosisRow, (breaker.id, parameter))
        calibration = stored_calibration(session, breaker=breaker, parameter=parameter, stored=stored, state=state)
    try:
        return prognose(state, history, limit, horizon_years=horizon_years, calibration=calibration), history, calibration
    except ValueError as exc:  # e.g. a non-positive baseline for a relative limit: say so, not a 500
        return (Prognosis(parameter, None, None, limit.describe(), status="no trend", reason=str(exc)), history,
                calibration)


def soonest_key(p) -> tuple:
    """Sort key: a crossing expected soonest first, then no crossing, then no trend."""
    q = p.operations_to_limit
    return (0, q.median) if q is not None and q.median is not None else ((1, 0.0) if p.status == "ok" else (2, 0.0))


def as_json(p) -> dict:
    """A prognosis as JSON-able dict (datetimes as ISO text)."""
    def conv(v):
        if isinstance(v, datetime):
            return v.isoformat()
        if isinstance(v, dict):
            return {k: conv(x) for k, x in v.items()}
        if isinstance(v, list):
            return [conv(x) for x in v]
        return v
    out = conv(asdict(p))
    out["summary"], out["fleet"] = words.summary(out), words.fleet_text(out)
    return out


# The stored prognosis (the fleet's column, SCADA, the prognosis notifications) is refreshed when
# new evidence could move it, not on every fit: it costs ~190 ms at 250 fits and ~380 ms at
# 1000 on this machine (docs/prognosis.md), and on every fit's path it made the 10,000-operation
# soak's capture-to-fit p95 grow 2.5x. A trend read from n fits has its standard error scaled by
# sqrt(n / (n + m)) after m more: m < n / REFRESH_SHARE moves it by < 2.5 %, a small part of
# its own 90 % interval. A crossing expected within q operations is refreshed every
# q / REFRESH_SHARE openings, so the stored count to the limit is never more than 5 % stale; an
# alarm, a logged repair, a baseline reset or an edited limit refresh it at once.
REFRESH_SHARE = 20


def _basis_key(limit, watched: bool, since: datetime | None) -> str:
    """What the stored prognosis was computed against besides the fits: a change refreshes it."""
    return f"{limit.describe()}|{'watched' if watched else 'not watched'}|{since.isoformat() if since else ''}"


def _fits_since(session, breaker: BreakerRow, parameter: str, as_of: dict) -> int:
    """The parameter's good fits after the stored prognosis's last one (``as_of``)."""
    from service.storage.crud_vibration import WATCHABLE, characteristic_history

    t = datetime.fromisoformat(as_of["time"])
    if parameter in WATCHABLE:
        rows = characteristic_history(session, breaker_id=breaker.id, name=parameter, since=t)
    else:
        rows = crud.good_parameter_history(session, breaker_id=breaker.id, name=parameter, since=t)
    return sum(1 for r in rows if (_aware(r.occurred_at), r.operation_id) > (_aware(t), as_of["operation_id"]))


def _aware(t: datetime) -> datetime:
    """SQLite gives naive UTC datetimes back, PostgreSQL aware ones: compare them alike."""
    from datetime import timezone

    return t.replace(tzinfo=timezone.utc) if t.tzinfo is None else t


def refresh_due(session, *, breaker: BreakerRow, parameter: str, limit, settings, stored: PrognosisRow | None) -> bool:
    """Does the stored prognosis of ``parameter`` need recomputing (``REFRESH_SHARE``)?"""
    if stored is None or not stored.result:
        return True
    r = stored.result
    key = _basis_key(limit, parameter in settings.watched, _restarted_at(session, breaker, parameter))
    if r.get("basis_key") != key or not r.get("as_of"):
        return parameter in settings.watched or r.get("basis_key") != key
    n = int(r.get("history_fits") or 0)
    q = (r.get("operations_to_limit") or {}).get("p05")
    span = min(n, q) if isinstance(q, (int, float)) else n
    return _fits_since(session, breaker, parameter, r["as_of"]) >= max(1, int(span // REFRESH_SHARE))


def _scored(session, breaker: BreakerRow, parameter: str, row: PrognosisRow | None, settings):
    """The calibration of a watched parameter brought up to date (``stored_calibration``); None
    for one the detector does not watch."""
    from service.alarms import DriftState

    if parameter not in settings.watched:
        return None
    srow = session.get(DriftStateRow, (breaker.id, parameter))
    state = DriftState.from_dict(srow.state) if srow is not None and srow.state else None
    return stored_calibration(session, breaker=breaker, parameter=parameter, stored=row, state=state)


def store_prognoses(session, *, breaker_id: int, settings, force: frozenset | set = frozenset()) -> list:
    """Refresh and store the breaker's prognoses that are due (``refresh_due``; every parameter
    in ``force``, e.g. one whose alarm just changed), and on every call score the fits since the
    last one into each parameter's calibration (cheap: ``stored_calibration``). Returns those
    recomputed."""
    breaker = session.get(BreakerRow, breaker_id)
    settings = settings.for_breaker(breaker.name)  # its [alarms.breakers.NAME] overrides
    now = utcnow()
    stored = {r.parameter: r for r in session.scalars(select(PrognosisRow).where(PrognosisRow.breaker_id == breaker_id))}
    progs = []
    for parameter, limit in limits_of(breaker).items():
        row = stored.pop(parameter, None)
        cal = _scored(session, breaker, parameter, row, settings)
        if parameter not in force and not refresh_due(session, breaker=breaker, parameter=parameter, limit=limit,
                                                      settings=settings, stored=row):
            if cal is not None and row is not None and row.result and cal.to_dict() != row.result.get(CALIBRATION):
                row.result = {**row.result, CALIBRATION: cal.to_dict()}  # a new dict: the JSON column is rewritten
            continue
        p, history, cal = parameter_prognosis(session, breaker=breaker, parameter=parameter, limit=limit,
                                              settings=settings, calibration=cal)
        cal = _after_prognosis(cal, p, history[-1] if history else None)
        row = row or PrognosisRow(breaker_id=breaker_id, parameter=parameter)
        q = p.operations_to_limit
        row.median_operations = float(q.median) if q is not None and q.median is not None else None
        last = history[-1] if history else None
        row.result = {**as_json(p), "history_fits": len(history),
                      "as_of": {"operation_id": last.operation_id, "time": _aware(last.time).isoformat()} if last else None,
                      "basis_key": _basis_key(limit, parameter in settings.watched, _restarted_at(session, breaker, parameter)),
                      **({CALIBRATION: cal.to_dict()} if cal is not None else {})}
        row.updated_at = now
        session.add(row)
        progs.append(p)
    for row in stored.values():  # a limit that was removed from the breaker file
        session.delete(row)
    return sorted(progs, key=soonest_key)


def soonest_by_breaker(session) -> dict[int, tuple[str, float | None, datetime]]:
    """breaker id -> (parameter, median operations to its limit, updated at) of the soonest
    stored crossing; the median is None when no limit is expected to be crossed within the
    horizon. A breaker without limits has no entry (SCADA points and the fleet's order)."""
    out: dict[int, tuple[str, float | None, datetime]] = {}
    for r in session.scalars(select(PrognosisRow).order_by(PrognosisRow.breaker_id, PrognosisRow.parameter)):
        have = out.get(r.breaker_id)
        if have is None or (r.median_operations is not None and (have[1] is None or r.median_operations < have[1])):
            out[r.breaker_id] = (r.parameter, r.median_operations, r.updated_at)
    return out


def soonest_texts(session) -> dict[int, str]:
    """breaker id -> the fleet column's words for the soonest stored prognosis (the one
    ``soonest_by_breaker`` picks)."""
    soonest = soonest_by_breaker(session)
    out = {}
    for r in session.scalars(select(PrognosisRow)):
        pick = soonest.get(r.breaker_id)
        if pick is not None and pick[0] == r.parameter and r.result:
            out[r.breaker_id] = r.result.get("fleet") or words.fleet_text(r.result)
    return out
