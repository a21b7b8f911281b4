"""Operators' alarm actions against the database: shelve, unshelve, out of service, return to
service, SCADA temperature, plus what the page and the API show about them (compensation state,
alarm history with first-out, the evidence series). The rules are in service.alarms.lifecycle;
this module only loads, applies and stores, with an audit row for every action."""

from __future__ import annotations

from datetime import datetime, timedelta

from service.alarms import lifecycle as lc
from service.storage import crud_alarms
from service.storage.models import AlarmRow, BreakerRow, utcnow

NOT_COMPENSATED = "not temperature-compensated"


def _view(a: AlarmRow) -> lc.AlarmView:
    return lc.AlarmView(id=a.id, state=a.state, shelved_until=a.shelved_until, shelved_at=a.shelved_at,
                        shelved_by=a.shelved_by, shelve_reason=a.shelve_reason)


def _store_view(a: AlarmRow, v: lc.AlarmView, now: datetime) -> None:
    a.shelved_until, a.shelved_at, a.shelved_by, a.shelve_reason = (v.shelved_until, v.shelved_at,
                                                                    v.shelved_by, v.shelve_reason)
    a.updated_at = now


def shelve(session, *, alarm: AlarmRow, by: str, minutes: float, reason: str) -> AlarmRow:
    now = utcnow()
    view, action = lc.shelve(_view(alarm), by=by, now=now, duration=timedelta(minutes=minutes), reason=reason)
    _store_view(alarm, view, now)
    crud_alarms.add_action(session, breaker_id=alarm.breaker_id, action=action)
    session.flush()
    return alarm


def unshelve(session, *, alarm: AlarmRow, by: str, reason: str = "") -> AlarmRow:
    now = utcnow()
    view, action = lc.unshelve(_view(alarm), by=by, now=now, reason=reason)
    _store_view(alarm, view, now)
    crud_alarms.add_action(session, breaker_id=alarm.breaker_id, action=action)
    session.flush()
    return alarm


def audit_acknowledge(session, *, alarm: AlarmRow, by: str, comment: str | None) -> None:
    """The acknowledgement itself is stored by crud.acknowledge_alarm; this audits it."""
    crud_alarms.add_action(session, breaker_id=alarm.breaker_id,
                           action=lc.Action("acknowledge", by, utcnow(), comment or "", None, alarm.id))


def _service(b: BreakerRow) -> lc.ServiceView:
    return lc.ServiceView(b.out_of_service_since, b.out_of_service_by, b.out_of_service_reason)


def take_out_of_service(session, *, breaker: BreakerRow, by: str, reason: str) -> None:
    svc, action = lc.take_out_of_service(_service(breaker), by=by, now=utcnow(), reason=reason)
    breaker.out_of_service_since, breaker.out_of_service_by, breaker.out_of_service_reason = (
        svc.out_of_service_since, svc.out_of_service_by, svc.out_of_service_reason)
    crud_alarms.add_action(session, breaker_id=breaker.id, action=action)
    session.flush()


def return_to_service(session, *, breaker: BreakerRow, by: str, reason: str, settings) -> int:
    """Maintenance over: back in service and the baseline reset (the mechanism may have been
    adjusted); returns the number of alarms the reset cleared."""
    from service.jobs.fit import reset_baseline

    svc, action = lc.return_to_service(_service(breaker), by=by, now=utcnow(), reason=reason)
    cleared = reset_baseline(session, breaker_id=breaker.id, by=by, settings=settings)
    breaker.out_of_service_since = breaker.out_of_service_by = breaker.out_of_service_reason = None
    crud_alarms.add_action(session, breaker_id=breaker.id, action=action)
    session.flush()
    return cleared


def set_temperature(session, *, breaker: BreakerRow, temperature_c: float, by: str) -> None:
    from service.alarms import check_temperature

    t = check_temperature(temperature_c, "temperature_c")
    crud_alarms.set_scada_temperature(session, breaker=breaker, temperature_c=t)
    session.flush()


def compensation(session, *, breaker_id: int, settings) -> dict[str, dict]:
    """Per watched parameter: is the baseline temperature-compensated, and what it has learnt."""
    from service.jobs.fit import _drift_state, breaker_settings

    settings = breaker_settings(session, breaker_id, settings)
    out = {}
    for p in settings.watched:
        _, state = _drift_state(session, breaker_id, p, settings)
        b = state.baseline
        comp = state.compensated
        out[p] = {"compensated": comp,
                  "status": "temperature-compensated" if comp else NOT_COMPENSATED,
                  "phase": state.phase,
                  "slope_rel_per_k": (b.slope / b.mean if comp and b.mean else None),
                  "slope_sd_rel_per_k": (b.slope_sd / b.mean if comp and b.mean else None),
                  "temperature_mean_c": b.t_mean if b else None,
                  "temperature_span_k": b.t_span if b else 0.0,
                  "baseline_fits": b.n if b else len(state.collected),
                  "baseline_frozen": state.frozen}
    return out


def history(session, *, breaker_id: int, now: datetime | None = None) -> list[dict]:
    """The breaker's alarms oldest first, numbered, with first-out, shelving and audit trail."""
    now = now or utcnow()
    rows = crud_alarms.alarm_history(session, breaker_id=breaker_id)
    actions = {}
    for a in crud_alarms.list_actions(session, breaker_id=breaker_id, limit=1000):
        actions.setdefault(a.alarm_id, []).append(a)
    out = []
    for i, a in enumerate(rows, 1):
        out.append({"order": i, "alarm": a, "first_out": bool(a.first_out),
                    "shelved": _view(a).shelved(now),
                    "actions": sorted(actions.get(a.id, []), key=lambda r: (r.at, r.id))})
    return out


def evidence(session, *, breaker_id: int, parameter: str, settings, limit: int = 2000) -> dict:
    """The detector's view of one parameter, fit by fit, replayed with the real detector: value,
    expected value and band (baseline at the fit's temperature), temperature, CUSUM, thresholds."""
    from service.alarms import drift

    breaker = session.get(BreakerRow, breaker_id)
    settings = settings.for_breaker(breaker.name)
    settings.direction(parameter)
    since = breaker.baseline_reset_at
    rows = crud_alarms.parameter_series(session, breaker_id=breaker_id, name=parameter, since=since)[-limit:]
    state = drift.DriftState.new(parameter, settings)
    series = {k: [] for k in ("operation_id", "time", "value", "ci_low", "ci_high", "temperature_c",
                              "expected", "band_low", "band_high", "statistic", "s_rising", "s_falling")}
    for op_id, t, v, lo, hi, temp in rows:
        obs = drift.FitObservation(operation_id=op_id, time=t, value=v, temperature=temp,
                                   ci95=(lo, hi) if lo is not None and hi is not None else None)
        try:
            state, _ = drift.update(state, obs, settings)
        except ValueError:
            continue
        monitoring = state.phase == "monitoring" and state.last_operation_id == op_id \
            and state.last_expected is not None and state.fits_monitored > 0
        exp, band = (state.last_expected, state.last_band) if monitoring else (None, None)
        for key, val in (("operation_id", op_id), ("time", t), ("value", v), ("ci_low", lo), ("ci_high", hi),
                         ("temperature_c", temp), ("expected", exp),
                         ("band_low", exp - 2 * band if exp is not None else None),
                         ("band_high", exp + 2 * band if exp is not None else None),
                         ("statistic", state.statistic if monitoring else None),
                         ("s_rising", state.s_rising if monitoring else None),
                         ("s_falling", state.s_falling if monitoring else None)):
            series[key].append(val)
    return {"parameter": parameter, "direction": settings.direction(parameter),
            "compensated": state.compensated,
            "status": "temperature-compensated" if state.compensated else NOT_COMPENSATED,
            "thresholds": {"k": settings.k, "warning": settings.h_warning, "alarm": settings.h_alarm,
                           "clear": settings.clear_level},
            "band_sigmas": 2.0, "series": series}
