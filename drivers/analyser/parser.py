"""One generic reader for every analyser :class:`~drivers.analyser.profile.Profile`.

Pure: text in, :class:`AnalyserRecord` out; no file access (``drivers.capture_file`` reads the
bytes). Every refusal is a :class:`~drivers.capture.CaptureError` naming the file and the line.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field

import numpy as np

from drivers.capture import CaptureError
from drivers.masked import describe, spans

from .profile import KIND_UNITS, TRAVEL, HeaderValue, Profile, normalise_key
from .profiles import PROFILES
from .values import is_over_range, read_date, read_number


@dataclass(frozen=True)
class Channel:
    """One table channel in its kind's unit (``KIND_UNITS``)."""

    name: str
    kind: str
    unit: str
    column: str
    data: np.ndarray
    wired: bool
    # Samples the analyser marked over-range (∞, NaN, OL): NaN in ``data``; None when there are none.
    mask: np.ndarray | None = None

    @property
    def over_range_throughout(self) -> bool:
        """Every sample over-range: the channel holds no reading."""
        return self.mask is not None and bool(self.mask.all())

    def masked_spans(self, sample_rate: float | None) -> list:
        """Its over-range spans (:func:`drivers.masked.spans`)."""
        return [] if self.mask is None else spans(self.name, self.mask, sample_rate)


@dataclass(frozen=True)
class AnalyserRecord:
    """An analyser export, read.

    ``sample_rate`` [Hz] is None for a bare export read without a rate; ``rate_source`` says
    where it came from. ``metadata`` and ``results`` hold the header's values (per channel as
    ``{name: {"T1": v, ...}}``); a value that could not be read stays as written (a ``str``) and
    is listed in ``unparsed`` (``{"name", "channel", "key", "line", "text", "why"}`` each);
    ``warnings`` what the reader noticed.
    """

    profile: str
    channels: tuple
    sample_rate: float | None
    rate_source: str | None
    metadata: dict
    results: dict
    warnings: list = field(default_factory=list)
    header_line: int = 0
    bare: bool = False
    unparsed: tuple = ()

    @property
    def samples(self) -> int:
        return int(self.channels[0].data.size) if self.channels else 0

    def wired(self, kind: str) -> list:
        return [c for c in self.channels if c.kind == kind and c.wired]

    def stated_stroke_mm(self, channel: str, profile: Profile | None = None) -> float | None:
        """The contact stroke the header states for a travel channel [mm], if any."""
        prof = profile or profile_named(self.profile)
        for name in prof.stated_stroke:
            for src in (self.results, self.metadata):
                v = src.get(name, {})
                v = v.get(channel) if isinstance(v, dict) else None
                if isinstance(v, (int, float)) and v > 0:
                    return float(v)
        return None


def profile_named(name: str) -> Profile:
    for p in PROFILES:
        if p.name == name:
            return p
    raise KeyError(name)


def find_profile(lines: list) -> tuple[Profile, int] | None:
    """The profile whose column-name line is in ``lines``, and that line's index; None if no
    known layout is recognised."""
    for prof in PROFILES:
        for i, line in enumerate(lines[: prof.header_lines_max]):
            if prof.recognises(line):
                return prof, i
    return None


def looks_like_analyser(text: str) -> bool:
    """Whether ``text`` is an export of a known analyser layout (content, not file name)."""
    return find_profile(text[:200_000].splitlines()) is not None


def parse_analyser(text: str, *, source: str, rate: float | None = None,
                   require_rate: bool = True) -> AnalyserRecord:
    """Read an analyser export.

    Parameters
    ----------
    text : str
        The decoded file (CRLF or LF).
    source : str
        File name for messages.
    rate : float, optional
        Sampling rate [Hz] for a bare export (no header stating it).
    require_rate : bool
        Refuse a bare export without ``rate`` (``hvcb inspect`` reads it anyway).
    """
    text = text.replace("\x1a", "").lstrip("\ufeff")
    lines = text.splitlines()
    found = find_profile(lines)
    if found is None:
        raise CaptureError(f"{source}: not a known analyser export (no line names coil-current and "
                           "contact-travel columns)")
    prof, h = found
    delim = _delimiter(lines[h])
    warnings: list[str] = []
    metadata: dict = {}
    results: dict = {}
    unparsed: list[dict] = []
    stated_rate = None
    rate_key = None
    for i, line in enumerate(lines[:h]):
        for key, value in _pairs(line, delim):
            r = _rate(prof, key, value, source, i + 1, unparsed, given=rate)
            if r is not None:
                if r > 0:
                    stated_rate, rate_key = r, key
                continue
            velocity = _match(prof.velocity_lines, key)
            if velocity is not None:
                hv, _ = velocity
                per = results.setdefault(hv.name, [])
                before = len(unparsed)
                per.append(_value(hv, value, key, i + 1, unparsed))
                if len(unparsed) > before:
                    unparsed[-1]["k"] = len(per) - 1
                continue
            for table, target in ((prof.metadata, metadata), (prof.results, results)):
                m = _match(table, key)
                if m is not None:
                    _store(target, m, _value(m[0], value, key, i + 1, unparsed))
                    break
    if unparsed:
        warnings.append(f"{len(unparsed)} header field(s) kept as written, not read: "
                        + "; ".join(f"line {u['line']} '{u['key']}' = '{u['text']}' ({u['why']})"
                                    for u in unparsed[:5]) + (" ..." if len(unparsed) > 5 else ""))
    channels, columns_skipped = _table(lines, h, prof, source, delim)
    if columns_skipped:
        warnings.append("columns not in the profile were ignored: " + ", ".join(columns_skipped))
    travel_names = [c.name for c in channels if c.kind == TRAVEL]
    for hv in prof.velocity_lines:  # k-th value -> k-th travel channel
        values = results.get(hv.name)
        if isinstance(values, list):
            results[hv.name] = {n: v for n, v in zip(travel_names, values)}
            for u in unparsed:  # the k-th value's channel, now known
                if u["name"] == hv.name and u["channel"] is None and isinstance(u.get("k"), int):
                    u["channel"] = travel_names[u["k"]] if u["k"] < len(travel_names) else None
    for u in unparsed:
        u.pop("k", None)
    bare = stated_rate is None and not any(metadata.values())
    if stated_rate is not None:
        if rate is not None and abs(rate - stated_rate) > 1e-6 * stated_rate:
            raise CaptureError(f"{source}: the file states {stated_rate / 1e3:g} kS/s ('{rate_key}') but "
                               f"--rate gives {rate / 1e3:g} kS/s; leave --rate out")
        sample_rate, rate_source = stated_rate, f"header: {rate_key}"
    elif rate is not None:
        if not (np.isfinite(rate) and rate > 0):
            raise CaptureError(f"{source}: --rate must be a positive number of samples per second, got {rate}")
        sample_rate, rate_source = float(rate), "--rate"
    elif require_rate:
        raise CaptureError(f"{source}: a bare analyser export (no header, so no stated sampling rate): "
                           "give the rate with --rate (e.g. --rate 10000 for 10 kS/s)")
    else:
        sample_rate, rate_source = None, None
        warnings.append("no sampling rate stated (bare export): give it with --rate")
    warnings += over_range_warnings(channels, sample_rate)
    unwired = [c.name for c in channels if not c.wired and not c.over_range_throughout]
    if unwired:
        warnings.append("not wired (constant reading, ignored): " + ", ".join(unwired))
    n = channels[0].data.size
    plot = metadata.get("plot_length_ms")
    if sample_rate and isinstance(plot, float) and plot > 0:
        length_ms = n / sample_rate * 1e3
        if abs(length_ms - plot) > max(2e3 / sample_rate, 0.01 * plot):
            warnings.append(f"the header's plot length is {plot:g} ms but the table holds "
                            f"{n} samples = {length_ms:g} ms at {sample_rate / 1e3:g} kS/s")
    return AnalyserRecord(profile=prof.name, channels=tuple(channels), sample_rate=sample_rate,
                          rate_source=rate_source, metadata=metadata, results=results,
                          warnings=warnings, header_line=h + 1, bare=bare, unparsed=tuple(unparsed))


def _delimiter(column_line: str) -> str:
    """``;`` for an export written with a decimal comma (European locales), else ``,``."""
    return ";" if column_line.count(";") > column_line.count(",") else ","


def _cells(line: str, delim: str) -> list:
    """One line's cells; a quoted cell keeps its delimiter (``"7,0"``)."""
    if '"' not in line:
        return line.split(delim)
    return next(csv.reader([line], delimiter=delim))


def _pairs(line: str, delim: str = ","):
    """``Key :,value,,Key2 :,value2`` -> (normalised key, value) pairs."""
    cells = _cells(line, delim)
    for k, cell in enumerate(cells):
        c = cell.strip()
        if c.endswith(":") and len(c) > 1:
            value = cells[k + 1].strip() if k + 1 < len(cells) else ""
            yield normalise_key(c), value


def _match(table, key: str):
    for hv in table:
        m = re.fullmatch(hv.pattern, key, re.IGNORECASE)
        if m is not None:
            return hv, m.groupdict().get("ch")
    return None


def _rate(prof: Profile, key, value, source, line_no, unparsed: list, given: float | None):
    """The stated rate [Hz]; 0 when the field is unreadable but ``given`` (--rate) stands in;
    None when ``key`` is no rate key. The rate times the waveform, so an unreadable one without
    --rate is refused."""
    for pattern, factor in prof.rate.items():
        if re.fullmatch(pattern, key, re.IGNORECASE):
            unit = {1e3: "kS/s", 1.0: "S/s"}.get(factor)
            v, why = read_number(value, unit)
            if why is None and isinstance(v, float) and v > 0:
                return v * factor
            why = why or "not a positive rate"
            if given is None:
                raise CaptureError(f"{source}, line {line_no}: '{key}' should be a number, got '{value[:20]}' "
                                   f"({why}); give the rate with --rate")
            unparsed.append({"name": "sample_rate", "channel": None, "key": key, "line": line_no,
                             "text": value, "why": why})
            return 0.0
    return None


def _value(hv: HeaderValue, value: str, key: str, line_no: int, unparsed: list):
    """One header value read as ``hv`` says (number, date or text); unreadable: kept as written
    and appended to ``unparsed``."""
    if hv.unit is not None:
        v, why = read_number(value, None if hv.unit == "-" else hv.unit)
    elif hv.date:
        v, why = read_date(value)
    else:
        return value
    if why is not None:
        ch = re.fullmatch(hv.pattern, key, re.IGNORECASE).groupdict().get("ch")
        unparsed.append({"name": hv.name, "channel": ch.upper() if ch else None, "key": key, "line": line_no,
                         "text": value, "why": why, "k": None})
    return v


def _store(target: dict, match, v):
    hv, ch = match
    if ch is None:
        target[hv.name] = v
    else:
        target.setdefault(hv.name, {})[ch.upper()] = v


def _table(lines, h, prof: Profile, source, delim: str = ","):
    names = [c.strip() for c in _cells(lines[h], delim)]
    picked = []  # (cell index, Column, channel number, column name)
    skipped = []
    for j, name in enumerate(names):
        if not name:
            continue  # blank separator (or trailing comma)
        for col in prof.columns:
            m = re.fullmatch(col.pattern, name, re.IGNORECASE)
            if m is not None:
                picked.append((j, col, m.group("n"), name))
                break
        else:
            skipped.append(f"'{name}'")
    if not picked:
        raise CaptureError(f"{source}, line {h + 1}: no known channel columns")
    idx = [p[0] for p in picked]
    need = max(idx) + 1
    rows = []
    first_row = None
    for i in range(h + 1, len(lines)):
        line = lines[i]
        if not line.strip(" ,\t"):
            continue  # blank line or a line of separators
        cells = line.split(delim)
        if delim == ";":  # decimal commas
            cells = [c.replace(",", ".") for c in cells]
        if len(cells) < need:
            raise CaptureError(f"{source}, line {i + 1}: {len(cells)} values, but the table's column "
                               f"names (line {h + 1}) need {need}")
        try:
            rows.append([float(cells[j]) for j in idx])
        except ValueError:
            rows.append([_sample(cells[j], source, i + 1, p[3]) for j, p in zip(idx, picked)])
        if first_row is None:
            first_row = i
    if len(rows) < 2:
        raise CaptureError(f"{source}: the table (from line {h + 1}) holds {len(rows)} sample rows")
    data = np.asarray(rows, dtype=float)
    bad = ~np.isfinite(data)  # over-range samples (float() reads "inf" and "nan" itself)
    channels = []
    for k, (j, col, n, name) in enumerate(picked):
        x = data[:, k] * col.factor
        mask = bad[:, k] if bad[:, k].any() else None
        x[~np.isfinite(x)] = np.nan
        good = x[np.isfinite(x)]
        channels.append(Channel(name=col.name.format(n=n), kind=col.kind, unit=KIND_UNITS[col.kind],
                                column=name, data=x, wired=bool(good.size and np.ptp(good) > 0), mask=mask))
    return channels, skipped


def _sample(cell: str, source: str, line_no: int, column: str) -> float:
    """One sample cell: a number, NaN for an over-range mark, else refused naming line and column."""
    try:
        return float(cell)
    except ValueError:
        if is_over_range(cell):
            return float("nan")
        raise CaptureError(f"{source}, line {line_no}, column '{column}': '{cell.strip()[:20]}' "
                           "is not a number") from None


def over_range_warnings(channels, sample_rate: float | None) -> list:
    """The record's over-range samples in words, one line per channel."""
    out = []
    for c in channels:
        if c.over_range_throughout:
            out.append(f"{c.name} ({c.column}): every sample is over-range (∞ or NaN): the channel holds "
                       "no reading and is not used")
        elif c.mask is not None:
            sp = c.masked_spans(sample_rate)
            out.append(f"{c.name} ({c.column}): {int(c.mask.sum())} over-range sample(s) masked in "
                       f"{len(sp)} span(s): " + "; ".join(describe(s).split(", ", 1)[1] for s in sp[:3])
                       + (" ..." if len(sp) > 3 else ""))
    return out


__all__ = ["AnalyserRecord", "Channel", "HeaderValue", "find_profile", "looks_like_analyser",
           "parse_analyser", "profile_named"]
