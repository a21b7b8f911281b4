"""The engineer's maintenance log: what each kind of work touches, and the detector's restart.

Pure. A logged event restarts the baseline, the alarms and the prognosis of the parameters it
touches at the time the work was done: the fits after it form a new baseline (a refilled buffer
is a new part as far as its damping goes), an active alarm of those parameters is cleared (the
work was its remedy), and the prognosis draws its trend from that time on. Without a logged
event nothing restarts: a level step stays a step in the trend, and the prognosis says so in
words (service.prognosis.forecast.change_words).

What each kind touches follows the model's parameters (docs/nomenclature.md):

- buffer refilled: the buffer's damping DO and stiffness EO (cb, kb);
- latch lubricated: the latch's release time (``latch_time_s``, issue 49) and the friction
  torques inside the resistance factors BO (TOf) and CC (TCf);
- spring replaced: the spring stiffness and force factors AO, BO, AC, CC and DC (kO, kC, xO);
- sensor remounted or recalibrated: every parameter (the transducer sees them all).
"""

from __future__ import annotations

from datetime import datetime

from service.alarms.observation import AlarmEvent
from service.alarms.state import DriftState

EVERY = "*"
KINDS: dict[str, tuple[str, ...]] = {
    "buffer refilled": ("DO", "EO"),
    "latch lubricated": ("latch_time_s", "BO", "CC"),
    "sensor remounted or recalibrated": (EVERY,),
    "spring replaced": ("AO", "BO", "AC", "CC", "DC"),
}


class MaintenanceError(ValueError):
    """A maintenance entry that cannot be logged: the message says why, in words."""


def touched(kind: str) -> tuple[str, ...]:
    """The parameters ``kind`` touches ("*": every one); MaintenanceError for an unknown kind."""
    try:
        return KINDS[kind]
    except KeyError:
        raise MaintenanceError(f"unknown maintenance kind {kind!r}: one of "
                               + ", ".join(f'"{k}"' for k in KINDS)) from None


def touches(kind: str, parameter: str) -> bool:
    t = touched(kind)
    return EVERY in t or parameter in t


def restart(state: DriftState, *, kind: str, done_at: datetime, by: str) -> tuple[DriftState, list[AlarmEvent]]:
    """The detector's state after ``kind`` was done at ``done_at`` by ``by``: a fresh state that
    learns a new baseline from the fits after ``done_at`` (fits before it are not fed again), and
    a "cleared" event for an active alarm. A state the work does not touch is returned as is."""
    if not isinstance(done_at, datetime) or done_at.tzinfo is None:
        raise MaintenanceError("the time the work was done must be a timezone-aware datetime")
    if not touches(kind, state.parameter):
        return state, []
    events = []
    if state.active:
        events.append(AlarmEvent(
            kind="cleared", parameter=state.parameter, level=state.level, episode=state.episode,
            operation_id=None, time=done_at,
            evidence={"baseline": state.baseline.to_dict() if state.baseline else None,
                      "statistic": state.statistic, "maintenance": kind, "done_by": str(by)},
            reason=f"maintenance logged: {kind} by {by}"))
    fresh = DriftState(parameter=state.parameter, episode=state.episode, last_operation_id=0, last_time=done_at)
    return fresh, events
