"""What happens to a drift state besides a new fit: replay, acknowledgement, baseline reset,
and the breaker's overall drift status. Pure, like drift.py."""

from __future__ import annotations

import math
from dataclasses import replace
from datetime import datetime
from typing import Any, Iterable, Mapping

from service.alarms.drift import update
from service.alarms.observation import AlarmEvent, FitObservation
from service.alarms.settings import DriftSettings
from service.alarms.state import DriftState


def replay(history: Iterable[FitObservation], settings: DriftSettings, *, parameter: str,
           state: DriftState | None = None) -> tuple[DriftState, list[AlarmEvent]]:
    """Run a whole history (in operation order) from a fresh state, or from ``state``."""
    state = state if state is not None else DriftState.new(parameter, settings)
    if state.parameter != parameter:
        raise ValueError(f"state is for {state.parameter!r}, not {parameter!r}")
    events: list[AlarmEvent] = []
    for obs in history:
        state, new = update(state, obs, settings)
        events.extend(new)
    return state, events


def acknowledge(state: DriftState, *, by: str, time: datetime) -> tuple[DriftState, list[AlarmEvent]]:
    """An operator acknowledges the active alarm. Acknowledging twice is a no-op.

    The alarm stays active until the statistic clears it; an escalation needs a new ack.
    """
    if not state.active:
        raise ValueError(f"no active {state.parameter} alarm to acknowledge")
    if not isinstance(time, datetime) or time.tzinfo is None:
        raise ValueError("acknowledgement time must be a timezone-aware datetime")
    if state.acknowledged:
        return state, []
    state = replace(state, acknowledged=True, acknowledged_by=str(by), acknowledged_at=time)
    return state, [AlarmEvent(kind="acknowledged", parameter=state.parameter, level=state.level,
                              episode=state.episode, operation_id=None, time=time,
                              evidence={"acknowledged_by": str(by)}, reason=f"acknowledged by {by}")]


def reset_baseline(state: DriftState, *, by: str, time: datetime,
                   reason: str = "maintenance") -> tuple[DriftState, list[AlarmEvent]]:
    """Admin action after maintenance: the next good fits form a new baseline.

    An active alarm is cleared (the fault it reported was the reason for the maintenance).
    """
    if not isinstance(time, datetime) or time.tzinfo is None:
        raise ValueError("baseline reset time must be a timezone-aware datetime")
    events = []
    if state.active:
        events.append(AlarmEvent(
            kind="cleared", parameter=state.parameter, level=state.level, episode=state.episode,
            operation_id=None, time=time,
            evidence={"baseline": state.baseline.to_dict() if state.baseline else None,
                      "statistic": state.statistic, "reset_by": str(by)},
            reason=f"baseline reset by {by}: {reason}"))
    fresh = DriftState(parameter=state.parameter, episode=state.episode,
                       last_operation_id=state.last_operation_id, last_time=state.last_time)
    return fresh, events


def observations_from_fit(fit: Any, *, operation_id: int | str, time: datetime,
                          settings: DriftSettings,
                          temperature: float | None = None) -> dict[str, FitObservation]:
    """The watched parameters of one fit (a ``FitResult`` or its ``to_dict()``) as observations.

    A watched name that is not a fitted parameter is read from the fit's ``characteristics``
    (e.g. ``latch_time_s``, the vibration's latch time [s]); a characteristic that is None (not
    read, its reason beside it) gives no observation. Only feed good fits (status ok) — a failed
    fit has no value to watch.
    """
    get = (lambda key: fit.get(key)) if isinstance(fit, Mapping) else (lambda key: getattr(fit, key, None))
    params, ci95, stderr = get("parameters") or {}, get("ci95") or {}, get("stderr")
    stderr = stderr if isinstance(stderr, Mapping) else {}
    chars = get("characteristics") or {}
    out = {}
    for name in settings.watched:
        if name in params:
            ci = ci95.get(name)
            out[name] = FitObservation(operation_id=operation_id, time=time, value=params[name],
                                       ci95=tuple(ci) if ci is not None else None,
                                       stderr=stderr.get(name), temperature=temperature)
        elif isinstance(chars, Mapping) and isinstance(chars.get(name), (int, float)) \
                and not isinstance(chars.get(name), bool) and math.isfinite(chars[name]):
            out[name] = FitObservation(operation_id=operation_id, time=time, value=float(chars[name]),
                                       temperature=temperature)
    return out


def never_fed(state: DriftState) -> bool:
    """No value of this parameter has reached the detector since its (re)start."""
    return state.phase == "baseline" and not state.collected and state.last_operation_id is None


def health_status(states: Iterable[DriftState], shelved: Iterable[str] = ()) -> str:
    """Overall drift status of a breaker: "alarm" | "warning" | "ok" | "unknown" (no baseline yet).

    The level of a parameter whose alarm an operator has ``shelved`` does not count while shelved.
    """
    states, shelved = list(states), set(shelved)
    # a watched parameter that has never had a value (the latch time of a breaker whose captures
    # carry no vibration) says nothing about the breaker: it neither alarms nor keeps it "unknown"
    fed = [s for s in states if not never_fed(s)]
    states = fed if fed else states
    levels = {s.level for s in states if s.parameter not in shelved}
    if "alarm" in levels:
        return "alarm"
    if "warning" in levels:
        return "warning"
    if not states or any(s.phase == "baseline" for s in states):
        return "unknown"
    return "ok"
