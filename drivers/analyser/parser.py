"""One generic reader for every analyser :class:`~drivers.analyser.profile.Profile`.

Pure: text in, :class:`AnalyserRecord` out; no file access (``drivers.capture_file`` reads the
bytes). Every refusal is a :class:`~drivers.capture.CaptureError` naming the file and the line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from drivers.capture import CaptureError

from .profile import KIND_UNITS, TRAVEL, HeaderValue, Profile, normalise_key
from .profiles import PROFILES


@dataclass(frozen=True)
class Channel:
    """One table channel in its kind's unit (``KIND_UNITS``)."""

    name: str
    kind: str
    unit: str
    column: str
    data: np.ndarray
    wired: bool


@dataclass(frozen=True)
class AnalyserRecord:
    """An analyser export, read.

    ``sample_rate`` [Hz] is None for a bare export read without a rate; ``rate_source`` says
    where it came from. ``metadata`` and ``results`` hold the header's values (per channel as
    ``{name: {"T1": v, ...}}``); ``warnings`` what the reader noticed.
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
    warnings: list[str] = []
    metadata: dict = {}
    results: dict = {}
    stated_rate = None
    rate_key = None
    header_keys = 0
    for i, line in enumerate(lines[:h]):
        for key, value in _pairs(line):
            header_keys += 1
            r = _rate(prof, key, value, source, i + 1)
            if r is not None:
                stated_rate, rate_key = r, key
                continue
            velocity = _match(prof.velocity_lines, key)
            if velocity is not None:
                hv, _ = velocity
                per = results.setdefault(hv.name, [])
                per.append(_number(value, source, i + 1, key))
                continue
            for table, target in ((prof.metadata, metadata), (prof.results, results)):
                m = _match(table, key)
                if m is not None:
                    _store(target, m, value, source, i + 1, key)
                    break
    channels, columns_skipped = _table(lines, h, prof, source)
    if columns_skipped:
        warnings.append("columns not in the profile were ignored: " + ", ".join(columns_skipped))
    travel_names = [c.name for c in channels if c.kind == TRAVEL]
    for hv in prof.velocity_lines:  # k-th value -> k-th travel channel
        values = results.get(hv.name)
        if isinstance(values, list):
            results[hv.name] = {n: v for n, v in zip(travel_names, values)}
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
    unwired = [c.name for c in channels if not c.wired]
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
                          warnings=warnings, header_line=h + 1, bare=bare)


def _pairs(line: str):
    """``Key :,value,,Key2 :,value2`` -> (normalised key, value) pairs."""
    cells = line.split(",")
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


def _rate(prof: Profile, key, value, source, line_no):
    for pattern, factor in prof.rate.items():
        if re.fullmatch(pattern, key, re.IGNORECASE):
            r = _number(value, source, line_no, key) * factor
            if not r > 0:
                raise CaptureError(f"{source}, line {line_no}: '{key}' must be a positive rate, got '{value}'")
            return r
    return None


def _number(value: str, source, line_no, key) -> float:
    try:
        v = float(value)
    except ValueError:
        raise CaptureError(f"{source}, line {line_no}: '{key}' should be a number, got '{value[:20]}'") from None
    if not np.isfinite(v):
        raise CaptureError(f"{source}, line {line_no}: '{key}' is not finite ('{value}')")
    return v


def _store(target: dict, match, value, source, line_no, key):
    hv, ch = match
    if hv.unit is not None:
        if value.upper() in ("NA", "N/A", "-", ""):
            v = None
        else:
            v = _number(value, source, line_no, key)
    else:
        v = value
    if ch is None:
        target[hv.name] = v
    else:
        target.setdefault(hv.name, {})[ch.upper()] = v


def _table(lines, h, prof: Profile, source):
    names = [c.strip() for c in lines[h].split(",")]
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
        cells = line.split(",")
        if len(cells) < need:
            raise CaptureError(f"{source}, line {i + 1}: {len(cells)} values, but the table's column "
                               f"names (line {h + 1}) need {need}")
        try:
            rows.append([float(cells[j]) for j in idx])
        except ValueError:
            for j, p in zip(idx, picked):
                try:
                    float(cells[j])
                except ValueError:
                    raise CaptureError(f"{source}, line {i + 1}, column '{p[3]}': '{cells[j].strip()[:20]}' "
                                       "is not a number") from None
        if first_row is None:
            first_row = i
    if len(rows) < 2:
        raise CaptureError(f"{source}: the table (from line {h + 1}) holds {len(rows)} sample rows")
    data = np.asarray(rows, dtype=float)
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise CaptureError(f"{source}: column '{picked[c][3]}' has a NaN or infinite value")
    channels = []
    for k, (j, col, n, name) in enumerate(picked):
        x = data[:, k] * col.factor
        channels.append(Channel(name=col.name.format(n=n), kind=col.kind, unit=KIND_UNITS[col.kind],
                                column=name, data=x, wired=bool(np.ptp(x) > 0)))
    return channels, skipped


__all__ = ["AnalyserRecord", "Channel", "HeaderValue", "find_profile", "looks_like_analyser",
           "parse_analyser", "profile_named"]
