"""What an event says: its kinds, and its JSON form (pure; ``schema.py`` documents it).

An event is one step of an alarm's life (ISA-18.2 terms, service.alarms.lifecycle) or of a
breaker's prognosis. Its ``id`` is the idempotency key a receiver deduplicates on; its
``sequence`` orders a breaker's events.
"""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Any

SCHEMA_VERSION = 1

# In the order they may happen within one stored change (an escalation breaks a shelve first).
ALARM_KINDS = ("raised", "unshelved", "escalated", "acknowledged", "shelved", "cleared")
PROGNOSIS_KINDS = ("prognosis_entered", "prognosis_left")
KINDS = ALARM_KINDS + PROGNOSIS_KINDS
SEVERITIES = ("warning", "alarm")

# Kinds a shelve does not silence: the shelve itself and its end are what people must hear of.
NOT_SILENCED_BY_SHELVING = ("shelved", "unshelved")


def utc_text(t: datetime | None) -> str | None:
    if t is None:
        return None
    if t.tzinfo is None:
        t = t.replace(tzinfo=timezone.utc)
    return t.astimezone(timezone.utc).isoformat().replace("+00:00", "Z")


def alarm_transitions(*, inserted: bool, old: dict[str, Any], new: dict[str, Any], now: datetime) -> list[str]:
    """The event kinds one stored change of an alarm row makes, in order.

    ``old`` holds the previous values of the fields that changed (state, level, shelved_until);
    ``new`` the row's values after the change.
    """
    if inserted:
        return ["raised"]
    kinds = []
    if "shelved_until" in old:
        before, after = old["shelved_until"], new["shelved_until"]
        was = before is not None and before > now
        now_shelved = after is not None and after > now
        if was and not now_shelved:
            kinds.append("unshelved")
        elif now_shelved and before != after:
            kinds.append("shelved")
    if "level" in old and old["level"] != new["level"] and new["state"] != "cleared":
        kinds.append("escalated")
    if "state" in old and old["state"] != new["state"]:
        if new["state"] == "acknowledged":
            kinds.append("acknowledged")
        elif new["state"] == "cleared":
            kinds.append("cleared")
    return sorted(kinds, key=ALARM_KINDS.index)


def silenced_reason(kind: str, *, shelved_until: datetime | None, out_of_service_since: datetime | None,
                    now: datetime) -> str | None:
    """Why an event reaches no route, or None: the page and SCADA stay quiet about a breaker out
    of service and about a shelved alarm (except for the shelve and its end)."""
    if out_of_service_since is not None:
        return f"breaker out of service since {utc_text(out_of_service_since)}"
    if kind not in NOT_SILENCED_BY_SHELVING and shelved_until is not None and shelved_until > now:
        return f"alarm shelved until {utc_text(shelved_until)}"
    return None


def alarm_payload(kind: str, *, key: str, alarm: dict[str, Any], breaker: dict[str, Any],
                  now: datetime) -> dict[str, Any]:
    """The JSON form of an alarm event (``sequence`` is filled in when it is sent)."""
    by, reason = None, None
    if kind == "acknowledged":
        by, reason = alarm.get("acknowledged_by"), alarm.get("ack_comment")
    elif kind == "shelved":
        by, reason = alarm.get("shelved_by"), alarm.get("shelve_reason")
    elif kind == "cleared":
        reason = ((alarm.get("evidence") or {}).get("cleared") or {}).get("reason")
    return {
        "id": key, "kind": kind, "occurred_at": utc_text(now),
        "breaker": breaker, "parameter": alarm["parameter"], "severity": alarm["level"],
        "by": by, "reason": reason,
        "alarm": {"id": alarm["id"], "state": alarm["state"], "level": alarm["level"],
                  "episode": alarm.get("episode", 0), "message": alarm.get("message") or "",
                  "raised_at": utc_text(alarm.get("raised_at")), "first_out": bool(alarm.get("first_out", True)),
                  "shelved_until": utc_text(alarm.get("shelved_until")) if kind == "shelved" else None,
                  "operation_id": alarm.get("operation_id")},
        "prognosis": None,
    }


def prognosis_payload(kind: str, *, key: str, breaker: dict[str, Any], parameter: str, weeks: float,
                      result: dict[str, Any], now: datetime) -> dict[str, Any]:
    """The JSON form of a prognosis event: the breaker's parameter is expected to reach its limit
    within ``weeks`` (``prognosis_entered``) or no longer is (``prognosis_left``)."""
    date = (result.get("date_to_limit") or {})
    ops = (result.get("operations_to_limit") or {})
    return {
        "id": key, "kind": kind, "occurred_at": utc_text(now),
        "breaker": breaker, "parameter": parameter, "severity": "warning",
        "by": None, "reason": None, "alarm": None,
        "prognosis": {"window_weeks": weeks, "status": result.get("status"),
                      "limit": result.get("limit_text"),
                      "date_to_limit": {k: date.get(k) for k in ("p05", "median", "p95")} if date else None,
                      "operations_to_limit": {k: ops.get(k) for k in ("p05", "median", "p95")} if ops else None},
    }


def headline(event: dict[str, Any]) -> str:
    """One line for a person: what happened to which breaker."""
    b = event["breaker"]
    who = b["name"] + (f" ({b['tag']})" if b.get("tag") else "")
    if event["alarm"] is not None:
        a = event["alarm"]
        text = f"{event['severity'].upper()} {event['kind']}: {who} {event['parameter']}"
        if event["kind"] in ("raised", "escalated") and a["message"]:
            text += f": {a['message']}"
        if event["by"]:
            text += f" (by {event['by']}" + (f": {event['reason']}" if event["reason"] else "") + ")"
        elif event["reason"]:
            text += f" ({event['reason']})"
        return text
    p = event["prognosis"]
    median = (p.get("date_to_limit") or {}).get("median")
    if event["kind"] == "prognosis_entered":
        when = f"median {median[:10]}" if median else ("limit crossed" if p["status"] == "crossed" else "soon")
        return (f"PROGNOSIS: {who} {event['parameter']} expected at its limit ({p['limit']}) within "
                f"{p['window_weeks']:g} weeks ({when})")
    return f"PROGNOSIS: {who} {event['parameter']} no longer expected at its limit within {p['window_weeks']:g} weeks"
