"""The breaker page's trend data, kept per breaker and extended as fits arrive.

A breaker with 10,000 operations has ~40,000 parameter values: reading and encoding them on
every page load costs more than the page's 1 s budget. The store keeps each breaker's columns
in memory, asks the database only for a version (counts and maxima) per request, appends new
rows when fits arrive in time order and rebuilds otherwise. What is sent is decimated for
display by min/max buckets (no excursion disappears) with the true count stated.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from threading import Event, Lock

from service.mechanics.nomenclature import CLOSING, OPENING, UNITS
from service.storage import crud, crud_web

from .series import (CHARACTERISTICS, DriftTraces, characteristics_series, epoch, finite_or_none,
                     minmax_indices)

DISPLAY_BUCKETS = 600  # per chart: ~1,200 plotted points, more than a chart has pixel columns


@dataclass
class _Columns:
    t: list = field(default_factory=list)          # datetime
    te: list = field(default_factory=list)         # epoch seconds
    op: list = field(default_factory=list)
    value: list = field(default_factory=list)
    lo: list = field(default_factory=list)
    hi: list = field(default_factory=list)
    ident: list = field(default_factory=list)


@dataclass
class _Entry:
    version: tuple
    max_id: int
    params: dict
    chars: dict
    body: bytes = b""


class TrendStore:
    def __init__(self, drift: DriftTraces | None = None, buckets: int = DISPLAY_BUCKETS):
        self.drift = drift or DriftTraces()
        self.buckets = buckets
        self._entries: dict[int, _Entry] = {}
        self._lock = Lock()
        self.warmed = Event()  # set when the start-up warm-up has finished

    def body(self, session, breaker, settings) -> bytes:
        """The JSON body of /ui/breakers/{id}/trends.json."""
        version = crud_web.trend_version(session, breaker_id=breaker.id)
        with self._lock:  # one builder at a time: the columns are extended in place
            entry = self._entries.get(breaker.id)
            if entry is not None and entry.version == version:
                return entry.body
            if entry is None or not self._extend(session, breaker.id, entry, version):
                entry = self._build(session, breaker.id, version)
            entry.version = version
            entry.body = self._encode(session, breaker, entry, settings)
            self._entries[breaker.id] = entry
            return entry.body

    def warm(self, Session, breaker_ids: list[int], settings, stop=None) -> None:
        """Bring the cache up to date (at start-up and after a fleet page is sent)."""
        for breaker_id in breaker_ids:
            if stop is not None and stop.is_set():
                return
            with Session() as session:
                breaker = crud.get_breaker(session, breaker_id=breaker_id)
                if breaker is not None:
                    self.body(session, breaker, settings)

    # -- columns -------------------------------------------------------------------------------
    def _build(self, session, breaker_id: int, version: tuple) -> _Entry:
        entry = _Entry(version=version, max_id=0, params={}, chars={})
        rows = crud_web.parameter_rows_after(session, breaker_id=breaker_id, after_id=0)
        self._append(entry, rows)
        entry.chars = characteristics_series(crud_web.characteristics_rows(session, breaker_id=breaker_id))
        return entry

    def _extend(self, session, breaker_id: int, entry: _Entry, version: tuple) -> bool:
        """Append rows stored since the entry was made; False when a rebuild is needed."""
        count, max_id = version[0], version[1]
        have = sum(len(c.value) for c in entry.params.values())
        if max_id < entry.max_id or count < have:
            return False
        rows = crud_web.parameter_rows_after(session, breaker_id=breaker_id, after_id=entry.max_id)
        if len(rows) != count - have:
            return False  # rows below max_id appeared or vanished
        for _, name, t, *_ in rows:
            col = entry.params.get(name)
            if col is not None and col.t and t < col.t[-1]:
                return False  # an older operation fitted late: keep operation order
        self._append(entry, rows)
        new_ops = sorted({r[3] for r in rows})
        if new_ops:
            more = characteristics_series(crud_web.characteristics_rows(session, breaker_id=breaker_id,
                                                                        operation_ids=new_ops))
            for kind, cols in more.items():
                mine = entry.chars.setdefault(kind, {k: [] for k in cols})
                for k, v in cols.items():
                    mine.setdefault(k, []).extend(v)
        return True

    @staticmethod
    def _append(entry: _Entry, rows) -> None:
        for row_id, name, t, op_id, value, lo, hi, ident in rows:
            c = entry.params.get(name)
            if c is None:
                c = entry.params[name] = _Columns()
            c.t.append(t)
            c.te.append(epoch(t))
            c.op.append(op_id)
            c.value.append(value)
            c.lo.append(lo)
            c.hi.append(hi)
            c.ident.append(bool(ident))
            entry.max_id = max(entry.max_id, row_id)

    # -- the body ------------------------------------------------------------------------------
    def _encode(self, session, breaker, entry: _Entry, settings) -> bytes:
        ds = settings.drift_settings.for_breaker(breaker.name)
        reset_at = breaker.baseline_reset_at
        alarms = crud.list_alarms(session, state="all", breaker_id=breaker.id)
        params = {}
        for name in OPENING + CLOSING:
            c = entry.params.get(name)
            if c is None or not c.value:
                continue
            drift = None
            if name in ds.watched:
                keep = [i for i, ok in enumerate(c.ident) if ok and (reset_at is None or c.t[i] >= reset_at)]
                from service.storage.crud_alarms import operation_temperatures

                temps = operation_temperatures(session, [c.op[i] for i in keep])
                tr = self.drift.trace(breaker.id, name, reset_at, [c.op[i] for i in keep], [c.t[i] for i in keep],
                                      [c.value[i] for i in keep], [c.lo[i] for i in keep],
                                      [c.hi[i] for i in keep], ds, temps=[temps.get(c.op[i]) for i in keep])
                idx = minmax_indices(tr["s"], self.buckets)
                drift = {**tr, "t": [tr["t"][i] for i in idx], "s": [tr["s"][i] for i in idx], "n": len(tr["t"])}
            op_time = dict(zip(c.op, c.te))
            idx = minmax_indices(c.value, self.buckets)
            params[name] = {
                "unit": UNITS[name], "n": len(c.value), "shown": int(idx.size),
                "t": [c.te[i] for i in idx], "value": [finite_or_none(c.value[i]) for i in idx],
                "lo": [finite_or_none(c.lo[i]) for i in idx], "hi": [finite_or_none(c.hi[i]) for i in idx],
                "op": [c.op[i] for i in idx], "drift": drift,
                "alarms": [{"t": op_time.get(a.operation_id, epoch(a.raised_at)), "level": a.level,
                            "state": a.state, "id": a.id} for a in alarms if a.parameter == name]}
        chars = {}
        for key, *_ in CHARACTERISTICS:
            per = {}
            for kind, cols in entry.chars.items():
                v = cols.get(key) or []
                idx = minmax_indices(v, self.buckets)
                per[kind] = {"t": [cols["t"][i] for i in idx], "v": [v[i] for i in idx], "n": len(v)}
            chars[key] = per
        body = {"breaker_id": breaker.id, "params": params, "characteristics": chars,
                "characteristic_labels": [[k, label, unit] for k, label, unit, _ in CHARACTERISTICS]}
        return json.dumps(body, separators=(",", ":"), allow_nan=False).encode()
