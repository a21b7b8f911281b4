"""One header or result cell of an analyser export, read tolerantly.

Field exports spell the same number many ways: ``765kV``, ``220 KV``, ``7,0`` (a decimal
comma), ``1.234,5``, ``∞``, ``1.#INF``, ``-nan(ind)``, ``NA`` or nothing; and dates as
``01-01-2026``, ``2026/01/31``, ``31.01.26`` or ``01-Jan-2026 14:03``. :func:`read_number` and
:func:`read_date` answer ``(value, why)``: the value, or ``None`` for an empty field, or the text
as written with ``why`` saying in words why it is not a number or a date. A cell never raises:
the parser keeps what it cannot read as text, flags it, and reads the waveform on.
"""

from __future__ import annotations

import math
import re
from datetime import datetime

# Spellings of "no value": the field is empty, not unreadable.
EMPTY = {"", "na", "n/a", "n.a.", "-", "--", "---", "none", "null", "nil"}
# Infinity and NaN as spreadsheets, C runtimes and analysers write them (lower case).
INFINITE = {"∞", "+∞", "-∞", "inf", "+inf", "-inf", "infinity", "+infinity", "-infinity", "infinite",
            "1.#inf", "-1.#inf", "1.#inf00", "-1.#inf00", "#inf", "oo"}
NOT_A_NUMBER = {"nan", "-nan", "+nan", "nan(ind)", "-nan(ind)", "1.#qnan", "-1.#qnan", "1.#ind", "-1.#ind",
                "#n/a", "#num!", "#value!", "#div/0!", "qnan", "snan"}

# What an analyser writes in a sample table for a reading outside its range ("OL" overload, "OVR").
# Lower case; infinities and NaNs count too. Such a sample is missing, not a refused record.
OVER_RANGE_WORDS = {"ol", "+ol", "-ol", "o/l", "ovr", "+ovr", "-ovr", "over", "overrange", "over range",
                    "over-range", "overflow", "underflow", "out of range", "oor"}


def is_over_range(text: str) -> bool:
    """Whether a sample cell is an over-range mark (``∞``, ``-∞``, ``NaN``, ``1.#INF``, ``OL``...)."""
    low = text.strip().strip('"').strip().lower()
    return low in INFINITE or low in NOT_A_NUMBER or low in OVER_RANGE_WORDS


_NUMBER = re.compile(r"^([+-]?(?:\d+(?:[.,' ]\d+)*|[.,]\d+)(?:[eE][+-]?\d+)?)\s*(.*)$")

# SI prefixes (case matters for m/M; an analyser's upper-case K is kilo).
_PREFIX = {"": 1.0, "k": 1e3, "K": 1e3, "M": 1e6, "m": 1e-3, "u": 1e-6, "µ": 1e-6, "μ": 1e-6}
# Base units a header field is stated in (compared in lower case). A sampling rate's "kC" is the
# analyser's "kilo-conversions" per second, and Hz is a sample per second: both are S/s.
_BASES = ("m/s", "ohm", "ω", "s/s", "hz", "v", "a", "s", "m", "c", "bar", "pa", "%")
_ALIAS = {"c": "s/s", "hz": "s/s", "ω": "ohm"}


def _split_unit(unit: str) -> tuple[float, str] | None:
    """``'kV'`` -> ``(1e3, 'v')``; None for a unit outside ``_BASES``."""
    u = unit.strip()
    if u.lower() in _BASES:
        return 1.0, _ALIAS.get(u.lower(), u.lower())
    for p, f in _PREFIX.items():
        base = u[len(p):].lower()
        if p and u.startswith(p) and base in _BASES:
            return f, _ALIAS.get(base, base)
    return None


def unit_factor(written: str, wanted: str) -> float | None:
    """The factor from a value in ``written`` to ``wanted`` (``'MV'`` -> ``'kV'``: 1000), or
    None when they are not the same quantity."""
    if written.strip().lower() == wanted.strip().lower():
        return 1.0
    a, b = _split_unit(written), _split_unit(wanted)
    if a is None or b is None or a[1] != b[1]:
        return None
    return a[0] / b[0]


def _decimal(text: str) -> float | None:
    """A number whose decimal mark is a point or a comma, with optional thousands marks."""
    t = text.replace("'", "").replace(" ", "")
    if "," in t and "." in t:  # the last mark is the decimal one: 1.234,5 or 1,234.5
        thousands = "." if t.rfind(",") > t.rfind(".") else ","
        t = t.replace(thousands, "").replace(",", ".")
    elif t.count(",") == 1:
        t = t.replace(",", ".")  # a decimal comma: 7,0
    elif t.count(",") > 1 or t.count(".") > 1:  # 1,234,567 or 1.234.567: thousands marks only
        t = t.replace(",", "").replace(".", "")
    try:
        return float(t)
    except ValueError:
        return None


def read_number(text: str, unit: str | None = None) -> tuple[float | str | None, str | None]:
    """``(value, why)`` of one cell meant as a number in ``unit``.

    ``value`` is a finite float (converted from a stated unit of the same quantity), ``None``
    for an empty field, or ``text`` itself when it is no finite number; ``why`` then says why.
    """
    raw = text.strip().strip('"').strip()
    low = raw.lower()
    if low in EMPTY:
        return None, None
    m = _NUMBER.match(raw)
    body, rest = (m.group(1), m.group(2).strip()) if m else (raw, "")
    # infinity or NaN, possibly followed by a unit ("∞ mm")
    head = low.split()[0] if low.split() else low
    for word in (low, head, body.lower()):
        if word in INFINITE:
            return raw, "infinite (the analyser's out-of-range mark), not a number"
        if word in NOT_A_NUMBER:
            return raw, "not a number (NaN)"
    if m is None:
        return raw, "not a number"
    value = _decimal(body)
    if value is None:
        return raw, "not a number"
    if rest:
        if unit is None or unit == "-":
            return raw, f"'{rest}' after the number, where no unit is expected"
        f = unit_factor(rest, unit)
        if f is None:
            return raw, f"in '{rest}', where {unit} is expected"
        value *= f
    if not math.isfinite(value):
        return raw, "infinite, not a number"
    return value, None


_MONTHS = {m: i for i, m in enumerate(("jan", "feb", "mar", "apr", "may", "jun", "jul", "aug", "sep", "oct",
                                       "nov", "dec"), start=1)}
_DATE_NUM = re.compile(r"(\d{1,4})[-/.](\d{1,2})[-/.](\d{1,4})")
_DATE_MON = re.compile(r"(\d{1,2})[-/. ]([A-Za-z]{3})[A-Za-z]*\.?[-/. ,]+(\d{2,4})")
_MON_DATE = re.compile(r"([A-Za-z]{3})[A-Za-z]*\.?[-/. ]+(\d{1,2})(?:st|nd|rd|th)?[-/., ]+(\d{2,4})")
_TIME = re.compile(r"(\d{1,2}):(\d{2})(?::(\d{2})(?:[.,](\d{1,6}))?)?\s*([AaPp][Mm])?")


def _year(y: int) -> int:
    return y + 2000 if y < 70 else y + 1900 if y < 100 else y


def read_date(text: str, *, day_first: bool = True) -> tuple[str | None, str | None]:
    """``(ISO 8601 date or date-time, why)`` of a date cell, in the forms field exports use:
    ``31-01-2026``, ``31/01/26``, ``31.01.2026``, ``2026-01-31``, ``31-Jan-2026``, ``Jan 31 2026``,
    each optionally with a time (``14:03``, ``14:03:22``, ``2:03 PM``). ``day_first``: how to read
    ``01/02/2026`` when both could be the month (a profile's setting; a part above 12 decides).
    Unreadable: ``(text, why)``; empty: ``(None, None)``."""
    raw = text.strip().strip('"').strip()
    if raw.lower() in EMPTY:
        return None, None
    y = mo = d = None
    if m := _DATE_NUM.search(raw):
        a, b, c = (int(g) for g in m.groups())
        if len(m.group(1)) == 4:  # year first: ISO
            y, mo, d = a, b, c
        elif a > 12 or (day_first and b <= 12):
            d, mo, y = a, b, _year(c)
        else:
            mo, d, y = a, b, _year(c)
    elif m := _DATE_MON.search(raw):
        d, mo, y = int(m.group(1)), _MONTHS.get(m.group(2).lower()), _year(int(m.group(3)))
    elif m := _MON_DATE.search(raw):
        mo, d, y = _MONTHS.get(m.group(1).lower()), int(m.group(2)), _year(int(m.group(3)))
    if y is None or mo is None:
        return raw, "not a date in a known form (e.g. 31-01-2026, 2026-01-31, 31-Jan-2026)"
    rest = raw[:m.start()] + " " + raw[m.end():]
    hh = mm = ss = us = 0
    timed = False
    if t := _TIME.search(rest):
        timed = True
        hh, mm = int(t.group(1)), int(t.group(2))
        ss = int(t.group(3) or 0)
        us = int((t.group(4) or "0").ljust(6, "0")[:6])
        if t.group(5):
            hh = hh % 12 + (12 if t.group(5).lower() == "pm" else 0)
    try:
        when = datetime(y, mo, d, hh, mm, ss, us)
    except ValueError as exc:
        return raw, f"not a valid date ({exc})"
    return (when.isoformat() if timed else when.date().isoformat()), None


__all__ = ["EMPTY", "INFINITE", "NOT_A_NUMBER", "OVER_RANGE_WORDS", "is_over_range", "read_date", "read_number", "unit_factor"]
