"""CSV exports of a breaker: its operations with every fitted parameter, its 95 % interval and
the travel characteristics (one row per operation), and its alarm history.

Both are generators of text chunks for a streamed answer: rows are read in keyset-paged chunks of
``CHUNK_ROWS`` (a short session per chunk, so no connection is held while the client reads), and
each chunk is written out before the next is read, so memory stays flat however long the history.
Times are ISO 8601 in UTC; each numeric column's header carries its unit in brackets; floats are
written with Python's shortest round-trip form, so re-reading gives the very numbers stored.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Iterator

from sqlalchemy import and_, or_, select

from service.mechanics.nomenclature import CLOSING, OPENING, machine_unit
from service.storage.models import AlarmRow, FitRow, OperationRow

from .window import Window, iso_z

# Rows per query: 1000 rows of ~40 columns are ~0.3 MB of text, and 10,000 operations take ten
# round trips (a few ms each), so neither the memory nor the query count grows with the history.
CHUNK_ROWS = 1000

PARAMETERS = OPENING + ("CO",) + CLOSING
# (stored key, column name, unit) of the travel characteristics (service.mechanics.characteristics)
CHARACTERISTICS = (("operating_time_s", "operating_time", "s"),
                   ("average_speed_rad_s", "average_speed", "rad/s"),
                   ("max_travel_rad", "max_travel", "rad"),
                   ("overtravel_rad", "overtravel", "rad"),
                   ("rebound_rad", "rebound", "rad"),
                   ("damping_time_s", "damping_time", "s"))


def _unit(name: str) -> str:
    return machine_unit(name) if name != "CO" else "s^-1"


def operation_header() -> list[str]:
    head = ["operation_id", "occurred_at [UTC]", "kind", "source", "clock_suspect", "temperature [C]",
            "temperature_source", "fit_status", "fit_version", "identifiable", "rmse [rad]"]
    for p in PARAMETERS:
        u = _unit(p)
        head += [f"{p} [{u}]", f"{p}_ci95_low [{u}]", f"{p}_ci95_high [{u}]"]
    head += [f"{name} [{unit}]" for _, name, unit in CHARACTERISTICS]
    return head


def _num(v) -> float | str:
    """A stored number as written: the float itself (shortest round-trip text), or empty."""
    if v is None:
        return ""
    try:
        return float(v)
    except (TypeError, ValueError):
        return ""


def operation_row(op: tuple) -> list:
    (op_id, at, kind, source, suspect, temp, temp_src, status, version, identifiable, rmse, params,
     ci, chars) = op
    params, ci, chars = params or {}, ci or {}, chars or {}
    row = [op_id, iso_z(at), kind, source, "true" if suspect else "false", _num(temp), temp_src or "",
           status or "", version if version is not None else "",
           "" if identifiable is None else ("true" if identifiable else "false"), _num(rmse)]
    for p in PARAMETERS:
        lo_hi = ci.get(p) or (None, None)
        row += [_num(params.get(p)), _num(lo_hi[0]), _num(lo_hi[1])]
    row += [_num(chars.get(key)) for key, _, _ in CHARACTERISTICS]
    return row


def _csv_text(rows) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\r\n")  # RFC 4180
    w.writerows(rows)
    return buf.getvalue()


def _keyset(query, time_col, id_col, after: tuple | None):
    """Rows strictly after ``after`` = (time, id) in (time, id) order."""
    if after is not None:
        t, i = after
        query = query.where(or_(time_col > t, and_(time_col == t, id_col > i)))
    return query.order_by(time_col, id_col).limit(CHUNK_ROWS)


def operation_chunks(Session: Callable, *, breaker_id: int, window: Window = Window()) -> Iterator[str]:
    """The operations CSV as text chunks: the header, then one chunk per ``CHUNK_ROWS`` operations,
    oldest first. ``Session`` is a session factory (one short session per chunk)."""
    yield _csv_text([operation_header()])
    base = (select(OperationRow.id, OperationRow.occurred_at, OperationRow.kind, OperationRow.source,
                   OperationRow.clock_suspect, OperationRow.temperature_c, OperationRow.temperature_source,
                   FitRow.status, FitRow.version, FitRow.identifiable, FitRow.rmse_rad, FitRow.parameters,
                   FitRow.ci95, FitRow.characteristics)
            .outerjoin(FitRow, FitRow.operation_id == OperationRow.id)
            .where(OperationRow.breaker_id == breaker_id, *window.where(OperationRow.occurred_at)))
    after = None
    while True:
        with Session() as session:
            rows = [tuple(r) for r in session.execute(_keyset(base, OperationRow.occurred_at, OperationRow.id, after))]
        if not rows:
            return
        yield _csv_text(operation_row(r) for r in rows)
        if len(rows) < CHUNK_ROWS:
            return
        after = (rows[-1][1], rows[-1][0])


ALARM_HEADER = ["alarm_id", "parameter", "unit", "level", "state", "episode", "first_out", "raised_at [UTC]",
                "acknowledged_at [UTC]", "acknowledged_by", "ack_comment", "cleared_at [UTC]",
                "shelved_until [UTC]", "shelved_by", "shelve_reason", "operation_id", "baseline_mean [unit]",
                "value_at_raise [unit]", "expected_at_raise [unit]", "change_at_raise [1]",
                "statistic_at_raise [z]", "threshold_alarm [z]", "message"]


def alarm_row(a: AlarmRow) -> list:
    ev = a.evidence or {}
    cur = ev.get("current") or {}
    base = ev.get("baseline") or {}
    th = ev.get("thresholds") or {}
    return [a.id, a.parameter, _unit(a.parameter) if a.parameter in PARAMETERS else "", a.level, a.state,
            a.episode, "true" if a.first_out else "false", iso_z(a.raised_at), iso_z(a.acknowledged_at),
            a.acknowledged_by or "", a.ack_comment or "", iso_z(a.cleared_at), iso_z(a.shelved_until),
            a.shelved_by or "", a.shelve_reason or "", a.operation_id if a.operation_id is not None else "",
            _num(base.get("mean")), _num(cur.get("value")), _num(cur.get("expected")), _num(cur.get("change_rel")),
            _num(ev.get("statistic")), _num(th.get("alarm")), a.message]


def alarm_chunks(Session: Callable, *, breaker_id: int, window: Window = Window()) -> Iterator[str]:
    """The alarm history CSV (raised in the window, oldest first) as text chunks."""
    yield _csv_text([ALARM_HEADER])
    base = select(AlarmRow).where(AlarmRow.breaker_id == breaker_id, *window.where(AlarmRow.raised_at))
    after = None
    while True:
        with Session() as session:
            alarms = list(session.scalars(_keyset(base, AlarmRow.raised_at, AlarmRow.id, after)))
            text = _csv_text(alarm_row(a) for a in alarms)
            last = (alarms[-1].raised_at, alarms[-1].id) if alarms else None
        if not alarms:
            return
        yield text
        if len(alarms) < CHUNK_ROWS:
            return
        after = last


def file_name(breaker_name: str, what: str, ext: str) -> str:
    """A download's file name: the breaker's name made safe for any file system."""
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in breaker_name).strip("._") or "breaker"
    return f"{safe}-{what}.{ext}"
