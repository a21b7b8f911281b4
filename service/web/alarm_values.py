"""An alarm's two values: when it was raised (its evidence) and now (the latest fit of its parameter).

An alarm's evidence is frozen when it is raised; a buffer leak keeps going afterwards, so a page
that showed only the evidence would label a stale value as current. Each value carries its change
from the alarm's baseline (the mean the drift statistic compares against).
"""

from __future__ import annotations

from service.mechanics.nomenclature import OPENING, UNITS
from service.storage import crud
from service.storage.crud_vibration import WATCHABLE


def _change(value, baseline) -> float | None:
    if value is None or not baseline:
        return None
    return float(value) / float(baseline) - 1.0


def _shown(name: str) -> tuple[float, str]:
    """(factor, unit) a parameter's values are shown in: a time in seconds (the trip latch's) in ms."""
    unit = UNITS.get(name, "")
    return (1e3, "ms") if unit == "s" else (1.0, unit)


def _scaled(v, k: float):
    if v is None:
        return None
    if isinstance(v, (list, tuple)):
        return [None if x is None else float(x) * k for x in v]
    return float(v) * k


def alarm_values(session, alarms) -> dict[int, dict]:
    """Per alarm id: ``unit``, ``baseline`` (its mean, for the changes), ``baseline_mean`` and
    ``baseline_sd`` (as shown), ``raised`` and ``now`` ({value, ci95, change_rel, operation_id,
    raw}, or None when there is no such value) of the alarm's parameter. Values are in the unit
    shown (``unit``: a latch time in ms); ``raw`` is the stored value in its own unit."""
    latest: dict[tuple[int, str], object] = {}
    out = {}
    for a in alarms:
        k, unit = _shown(a.parameter)
        ev = a.evidence or {}
        cur = ev.get("current") or {}
        base = ev.get("baseline") or {}
        baseline = cur.get("expected") or base.get("mean")
        raised = None
        if cur.get("value") is not None:
            raised = {"value": cur["value"] * k, "raw": cur["value"], "ci95": _scaled(cur.get("ci95"), k),
                      "operation_id": cur.get("operation_id"),
                      "change_rel": cur.get("change_rel") if cur.get("change_rel") is not None
                      else _change(cur["value"], baseline)}
        # the vibration's characteristics (the latch time) are read from openings
        kind = "open" if a.parameter in OPENING or a.parameter in WATCHABLE else "close"
        key = (a.breaker_id, kind)
        if key not in latest:
            latest[key] = crud.latest_fit(session, breaker_id=a.breaker_id, kind=kind)
        fit = latest[key]
        now = None
        value = None if fit is None else ((fit.parameters or {}).get(a.parameter) if a.parameter not in WATCHABLE
                                          else (fit.characteristics or {}).get(a.parameter))
        if isinstance(value, (int, float)):
            now = {"value": value * k, "raw": value, "ci95": _scaled((fit.ci95 or {}).get(a.parameter), k),
                   "operation_id": fit.operation_id, "change_rel": _change(value, baseline)}
        out[a.id] = {"unit": unit, "baseline": baseline, "baseline_mean": _scaled(base.get("mean"), k),
                     "baseline_sd": _scaled(base.get("sd"), k), "raised": raised, "now": now}
    return out
