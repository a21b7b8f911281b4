"""What operators do to alarms and breakers, as a pure state machine (ISA-18.2 terms).

An alarm is ``raised`` → ``acknowledged`` → ``cleared`` (the detector clears it; an escalation
makes it unacknowledged again). Orthogonal to that, an active alarm may be **shelved**: marked
shelved for a stated time, with a reason; it unshelves by itself when the time is up.
A breaker may be **out of service** (maintenance): its fits are not watched, and returning it
to service resets the baseline. Every action returns an ``Action`` for the audit trail.

Pure: times are passed in; the service stores the result (service/jobs/alarm_actions.py).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from datetime import datetime, timedelta

# Longest shelving: ISA-18.2 asks for a time limit; one shift-week covers a planned outage
# without letting a forgotten shelve hide an alarm for good.
MAX_SHELVE = timedelta(days=7)
MIN_REASON = 3  # characters: "a reason" means words, not an empty string


class LifecycleError(ValueError):
    """An action that is not allowed in the current state; the message says why."""


@dataclass(frozen=True)
class AlarmView:
    """The lifecycle fields of one alarm."""

    id: int
    state: str  # raised | acknowledged | cleared
    shelved_until: datetime | None = None
    shelved_at: datetime | None = None
    shelved_by: str | None = None
    shelve_reason: str | None = None

    @property
    def active(self) -> bool:
        return self.state in ("raised", "acknowledged")

    def shelved(self, now: datetime) -> bool:
        """Shelved at ``now`` (a shelve ends by itself at ``shelved_until``)."""
        return self.active and self.shelved_until is not None and now < self.shelved_until


@dataclass(frozen=True)
class Action:
    """One audited action: who did what, when, why (and until when)."""

    action: str
    by: str
    at: datetime
    reason: str = ""
    until: datetime | None = None
    alarm_id: int | None = None


def _who_why(by: str, reason: str | None, *, need_reason: bool) -> tuple[str, str]:
    by = (by or "").strip()
    if not by:
        raise LifecycleError("the action needs the name of who does it")
    reason = (reason or "").strip()
    if need_reason and len(reason) < MIN_REASON:
        raise LifecycleError(f"give a reason (at least {MIN_REASON} characters)")
    return by, reason


def _aware(t: datetime, what: str) -> None:
    if not isinstance(t, datetime) or t.tzinfo is None:
        raise LifecycleError(f"{what} must be a timezone-aware time")


def shelve(alarm: AlarmView, *, by: str, now: datetime, duration: timedelta,
           reason: str) -> tuple[AlarmView, Action]:
    """Shelve an active alarm for ``duration`` (at most MAX_SHELVE), with a reason.

    Shelving a shelved alarm again replaces its end time (and is audited again).
    """
    _aware(now, "the time")
    by, reason = _who_why(by, reason, need_reason=True)
    if not alarm.active:
        raise LifecycleError(f"alarm {alarm.id} is cleared; only an active alarm can be shelved")
    if duration <= timedelta(0):
        raise LifecycleError("the shelving time must be positive")
    if duration > MAX_SHELVE:
        raise LifecycleError(f"an alarm can be shelved for at most {MAX_SHELVE.days} days, "
                             f"asked {duration}")
    until = now + duration
    new = replace(alarm, shelved_until=until, shelved_at=now, shelved_by=by, shelve_reason=reason)
    return new, Action("shelve", by, now, reason, until, alarm.id)


def unshelve(alarm: AlarmView, *, by: str, now: datetime, reason: str = "") -> tuple[AlarmView, Action]:
    """End a shelve before its time."""
    _aware(now, "the time")
    by, reason = _who_why(by, reason, need_reason=False)
    if not alarm.shelved(now):
        raise LifecycleError(f"alarm {alarm.id} is not shelved")
    new = replace(alarm, shelved_until=now)
    return new, Action("unshelve", by, now, reason, None, alarm.id)


def acknowledge(alarm: AlarmView, *, by: str, now: datetime, comment: str = "") -> tuple[AlarmView, Action]:
    """Acknowledge a raised alarm (acknowledging an acknowledged one is refused: nothing to do)."""
    _aware(now, "the time")
    by, comment = _who_why(by, comment, need_reason=False)
    if alarm.state == "cleared":
        raise LifecycleError(f"alarm {alarm.id} is cleared; nothing to acknowledge")
    if alarm.state == "acknowledged":
        raise LifecycleError(f"alarm {alarm.id} is already acknowledged")
    return replace(alarm, state="acknowledged"), Action("acknowledge", by, now, comment, None, alarm.id)


@dataclass(frozen=True)
class ServiceView:
    """A breaker's service state: in service unless ``out_of_service_since`` is set."""

    out_of_service_since: datetime | None = None
    out_of_service_by: str | None = None
    out_of_service_reason: str | None = None

    @property
    def in_service(self) -> bool:
        return self.out_of_service_since is None


def take_out_of_service(svc: ServiceView, *, by: str, now: datetime,
                        reason: str) -> tuple[ServiceView, Action]:
    """Maintenance starts: the breaker's fits are no longer watched."""
    _aware(now, "the time")
    by, reason = _who_why(by, reason, need_reason=True)
    if not svc.in_service:
        raise LifecycleError(f"the breaker is already out of service since "
                             f"{svc.out_of_service_since.isoformat()} ({svc.out_of_service_reason})")
    return ServiceView(now, by, reason), Action("out_of_service", by, now, reason)


def return_to_service(svc: ServiceView, *, by: str, now: datetime,
                      reason: str = "") -> tuple[ServiceView, Action]:
    """Maintenance ends: the caller resets the baseline (the mechanism may have changed)."""
    _aware(now, "the time")
    by, reason = _who_why(by, reason, need_reason=False)
    if svc.in_service:
        raise LifecycleError("the breaker is in service")
    return ServiceView(), Action("return_to_service", by, now,
                                 reason or f"maintenance since {svc.out_of_service_since.isoformat()} ended")


def first_out(raised_at: list[tuple[int, datetime, datetime | None]]) -> dict[int, bool]:
    """First-out flags of a breaker's alarms ``(id, raised_at, cleared_at or None)``: an alarm is
    first-out when no other alarm of the breaker was active when it was raised (ISA-18.2: the
    first of a cascade is the one that names the cause)."""
    out: dict[int, bool] = {}
    rows = sorted(raised_at, key=lambda r: (r[1], r[0]))
    for i, (aid, t, _) in enumerate(rows):
        out[aid] = not any(t0 <= t and (c0 is None or c0 > t) for _, t0, c0 in rows[:i])
    return out
