"""The webhook body's JSON Schema (draft 2020-12), version ``SCHEMA_VERSION``.

docs/notifications.md shows it; a test checks that the page's copy is this one and that every
body the notifier sends validates against it. A new field is a compatible change; a removed or
retyped field bumps ``schema_version``.
"""

from __future__ import annotations

from service.notifications.events import ALARM_KINDS, KINDS, SCHEMA_VERSION, SEVERITIES

_TIME = {"type": "string", "format": "date-time", "description": "UTC, ISO 8601 with Z"}
_NULLABLE_TIME = {"type": ["string", "null"], "format": "date-time"}
_QUANTILES = {"type": ["object", "null"], "properties": {k: {} for k in ("p05", "median", "p95")}}

EVENT = {
    "type": "object",
    "required": ["id", "sequence", "kind", "occurred_at", "breaker", "parameter", "severity", "by", "reason",
                 "alarm", "prognosis"],
    "additionalProperties": False,
    "properties": {
        "id": {"type": "string", "description": "the event's idempotency key (unique, stable across retries)"},
        "sequence": {"type": "integer", "description": "increases with every event; orders a breaker's events"},
        "kind": {"enum": list(KINDS)},
        "occurred_at": _TIME,
        "breaker": {"type": "object", "required": ["id", "name", "tag"], "additionalProperties": False,
                    "properties": {"id": {"type": "integer"}, "name": {"type": "string"},
                                   "tag": {"type": ["string", "null"], "description": "SCADA designation"}}},
        "parameter": {"type": ["string", "null"], "description": "the fitted parameter, e.g. DO or BO"},
        "severity": {"enum": list(SEVERITIES)},
        "by": {"type": ["string", "null"], "description": "who acknowledged or shelved"},
        "reason": {"type": ["string", "null"], "description": "the comment, shelve reason or clearing reason"},
        "alarm": {
            "type": ["object", "null"], "description": f"for the kinds {', '.join(ALARM_KINDS)}",
            "required": ["id", "state", "level", "episode", "message", "raised_at", "first_out", "shelved_until",
                         "operation_id"],
            "additionalProperties": False,
            "properties": {"id": {"type": "integer"}, "state": {"enum": ["raised", "acknowledged", "cleared"]},
                           "level": {"enum": list(SEVERITIES)}, "episode": {"type": "integer"},
                           "message": {"type": "string"}, "raised_at": _NULLABLE_TIME,
                           "first_out": {"type": "boolean"}, "shelved_until": _NULLABLE_TIME,
                           "operation_id": {"type": ["integer", "null"]}}},
        "prognosis": {
            "type": ["object", "null"], "description": "for prognosis_entered and prognosis_left",
            "required": ["window_weeks", "status", "limit", "date_to_limit", "operations_to_limit"],
            "additionalProperties": False,
            "properties": {"window_weeks": {"type": "number"}, "status": {"type": ["string", "null"]},
                           "limit": {"type": ["string", "null"]}, "date_to_limit": _QUANTILES,
                           "operations_to_limit": _QUANTILES}},
    },
}

SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$id": f"https://hvcb.invalid/schemas/notification-{SCHEMA_VERSION}.json",
    "title": "hvcb notification message",
    "type": "object",
    "required": ["schema_version", "message_id", "page_url", "events"],
    "additionalProperties": False,
    "properties": {
        "schema_version": {"const": SCHEMA_VERSION},
        "message_id": {"type": "string", "description": "the Idempotency-Key header: the event's id when the "
                       "message carries one event, a digest of the events' ids for a group"},
        "page_url": {"type": ["string", "null"]},
        "events": {"type": "array", "minItems": 1, "items": EVENT,
                   "description": "oldest first; more than one when a storm was grouped"},
    },
}
