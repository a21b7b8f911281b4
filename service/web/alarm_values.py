"""An alarm's two values: when it was raised (its evidence) and now (the latest fit of its parameter).

An alarm's evidence is frozen when it is raised; a buffer leak keeps going afterwards, so a page
that showed only the evidence would label a stale value as current. Each value carries its change
from the alarm's baseline (the mean the drift statistic compares against).
"""

from __future__ import annotations

from service.mechanics.nomenclature import OPENING, UNITS
from service.storage import crud


def _change(value, baseline) -> float | None:
    if value is None or not baseline:
        return None
    return float(value) / float(baseline) - 1.0


def alarm_values(session, alarms) -> dict[int, dict]:
    """Per alarm id: ``unit``, ``baseline``, ``raised`` and ``now`` ({value, ci95, change_rel,
    operation_id}, or None when there is no such value) of the alarm's parameter."""
    latest: dict[tuple[int, str], object] = {}
    out = {}
    for a in alarms:
        ev = a.evidence or {}
        cur = ev.get("current") or {}
        baseline = cur.get("expected") or (ev.get("baseline") or {}).get("mean")
        raised = None
        if cur.get("value") is not None:
            raised = {"value": cur["value"], "ci95": cur.get("ci95"), "operation_id": cur.get("operation_id"),
                      "change_rel": cur.get("change_rel") if cur.get("change_rel") is not None
                      else _change(cur["value"], baseline)}
        kind = "open" if a.parameter in OPENING else "close"
        key = (a.breaker_id, kind)
        if key not in latest:
            latest[key] = crud.latest_fit(session, breaker_id=a.breaker_id, kind=kind)
        fit = latest[key]
        now = None
        if fit is not None and fit.parameters and fit.parameters.get(a.parameter) is not None:
            value = fit.parameters[a.parameter]
            now = {"value": value, "ci95": (fit.ci95 or {}).get(a.parameter), "operation_id": fit.operation_id,
                   "change_rel": _change(value, baseline)}
        out[a.id] = {"unit": UNITS.get(a.parameter, ""), "baseline": baseline, "raised": raised, "now": now}
    return out
