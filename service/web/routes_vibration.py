"""The operation page's vibration read: this operation's envelope against the breaker's
fingerprint band, its events and latch time (service/vibration, stored in the fit's
characteristics), for a signed-in engineer."""

from __future__ import annotations

import json
import math

from fastapi import APIRouter, Request
from fastapi.responses import Response

from service.storage import crud
from service.storage.crud_vibration import breaker_fingerprint

from .handlers import Id, Reader, db_session, not_found
from .render import security_headers

router = APIRouter(include_in_schema=False)

EVENT_WORDS = {"first_shock": "first shock (trip strike)", "latch_release": "latch release",
               "buffer_engagement": "buffer engagement", "end_stop": "end stop", "impact": "impact"}


def _g_of_db(v):
    return None if v is None else round(10 ** (v / 20.0), 4)


def vibration_view(ch: dict | None, fp) -> dict:
    """The chart's data from one fit's characteristics and the breaker's fingerprint (or None)."""
    ch = ch or {}
    env = ch.get("vibration_envelope")
    out = {"latch_time_s": ch.get("latch_time_s"), "reason": ch.get("latch_time_reason"),
           "events": [{**e, "label": EVENT_WORDS.get(e["name"], e["name"])} for e in ch.get("vibration_events") or []],
           "envelope": None, "fingerprint": None, "shift": None, "detection": ch.get("vibration")}
    if env:
        out["envelope"] = {"t_ms": [round((env["t0_s"] + (i + 0.5) * env["dt_s"]) * 1e3, 4) for i in range(len(env["g"]))],
                           "g": env["g"]}
    if fp is not None:
        out["fingerprint"] = {"count": fp.count_, "operation_ids": fp.operation_ids_, "latch": fp.latch_,
                              "events": fp.events_}
        e = fp.envelope_
        if e and env and len(e["mean_db"]) == len(env["g"]):
            # a block seen in one healthy operation only has a level but no spread: no band there
            lo = [None if m is None or s is None else m - 3 * s for m, s in zip(e["mean_db"], e["sd_db"])]
            hi = [None if m is None or s is None else m + 3 * s for m, s in zip(e["mean_db"], e["sd_db"])]
            out["fingerprint"].update(mean_g=[_g_of_db(v) for v in e["mean_db"]], lo_g=[_g_of_db(v) for v in lo],
                                      hi_g=[_g_of_db(v) for v in hi])
        if ch.get("vibration_events"):
            out["shift"] = fp.shift(ch)
    return out


@router.get("/ui/operations/{operation_id}/vibration.json")
def operation_vibration(request: Request, operation_id: Id, user: Reader):
    with db_session(request) as session:
        op = crud.get_operation(session, operation_id=operation_id) or not_found(f"operation {operation_id}")
        ch = op.fit.characteristics if op.fit is not None and op.fit.status == "done" else None
        fp = breaker_fingerprint(session, breaker_id=op.breaker_id, kind=op.kind)
    body = vibration_view(ch, fp)
    body.update(operation_id=operation_id, kind=op.kind)
    return security_headers(Response(json.dumps(_finite(body), allow_nan=False), media_type="application/json"))


def _finite(v):
    """NaN and ±inf as null, recursively (JSON has no NaN)."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x) for x in v]
    return v
