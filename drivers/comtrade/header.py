"""The CFG header of a COMTRADE record, read leniently (C37.111 1991, 1999, 2013 and the
non-standard variants relays write), and rewritten in a canonical form the ``comtrade``
package reads.

Repairs are recorded as sentences in ``Header.warnings``; what cannot be repaired raises
CaptureError naming the file and the line.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from drivers.capture import CaptureError

FILE_TYPES = ("ASCII", "BINARY", "BINARY32", "FLOAT32")
STANDARD_REVISIONS = ("1991", "1999", "2001", "2013")
_DATE = re.compile(r"^(\d{1,2})/(\d{1,2})/(\d{2,4})$")
_TIME = re.compile(r"^(\d{1,2}):(\d{1,2}):(\d{1,2})(?:[.,](\d{1,12}))?$")
_TIME_CODE = re.compile(r"^([+-]?)(\d{1,2})(?:h(\d{1,2}))?$", re.IGNORECASE)


@dataclass
class AnalogChannel:
    index: int
    name: str
    phase: str
    circuit: str
    unit: str
    a: float
    b: float
    skew: float
    cmin: float
    cmax: float
    primary: float = 1.0
    secondary: float = 1.0
    ps: str = "P"


@dataclass
class DigitalChannel:
    index: int
    name: str
    phase: str = ""
    circuit: str = ""
    normal: int = 0


@dataclass
class Stamp:
    """A CFG date and time, kept as written so nanoseconds and local offsets survive."""

    year: int
    month: int
    day: int
    hour: int
    minute: int
    second: int
    fraction: str  # the digits after the decimal point, as written

    @property
    def nanoseconds(self) -> bool:
        return len(self.fraction) > 6

    def iso(self, offset_minutes: int | None = None) -> str:
        s = (f"{self.year:04d}-{self.month:02d}-{self.day:02d}T{self.hour:02d}:{self.minute:02d}:"
             f"{self.second:02d}")
        if self.fraction:
            s += "." + self.fraction
        if offset_minutes is not None:
            sign = "-" if offset_minutes < 0 else "+"
            m = abs(offset_minutes)
            s += f"{sign}{m // 60:02d}:{m % 60:02d}"
        return s

    def cfg_text(self, month_first: bool) -> str:
        d = (f"{self.month:02d}/{self.day:02d}" if month_first else f"{self.day:02d}/{self.month:02d}")
        frac = ("." + self.fraction) if self.fraction else ""
        return f"{d}/{self.year:04d},{self.hour:02d}:{self.minute:02d}:{self.second:02d}{frac}"


@dataclass
class Header:
    name: str  # the file the header came from, for messages
    station: str
    device: str
    revision: str  # as written ("" for 1991 files that name none)
    analog: list
    digital: list
    line_frequency: float | None
    nrates: int
    rates: list  # [(rate_hz, last_sample_number)]
    start: Stamp | None
    trigger: Stamp | None
    file_type: str
    time_multiplier: float = 1.0
    time_code: str = ""
    local_code: str = ""
    warnings: list = field(default_factory=list)

    @property
    def standard_revision(self) -> str:
        """The revision whose rules apply: 1991, 1999 or 2013."""
        if self.revision == "1991" or self.revision == "":
            return "1991"
        if self.revision == "2013" or self.file_type in ("BINARY32", "FLOAT32") or self.time_code:
            return "2013"
        return "1999"

    @property
    def declared_samples(self) -> int:
        return int(self.rates[-1][1]) if self.rates else 0

    @property
    def time_base(self) -> float:
        """Unit of the DAT time stamps [s]: µs, or ns when the CFG times carry nanoseconds."""
        ns = any(s is not None and s.nanoseconds for s in (self.start, self.trigger))
        return 1e-9 if ns else 1e-6

    @property
    def utc_offset_minutes(self) -> int | None:
        return parse_time_code(self.time_code)

    def canonical_text(self, rates: list) -> str:
        """The header in the form the ``comtrade`` package reads, with the given rate sections."""
        rev = self.standard_revision
        if rev == "1991" and self.file_type != "ASCII":
            rev = "1999"  # the package takes raw -1 for "missing" in 1991 binary data; it is a value
        lines = [f"{_clean(self.station)},{_clean(self.device)}" + ("" if rev == "1991" else f",{rev}"),
                 f"{len(self.analog) + len(self.digital)},{len(self.analog)}A,{len(self.digital)}D"]
        for i, ch in enumerate(self.analog, 1):
            lines.append(f"{i},{_clean(ch.name)},{_clean(ch.phase)},{_clean(ch.circuit)},{_clean(ch.unit)},"
                         f"{ch.a!r},{ch.b!r},{ch.skew!r},{ch.cmin!r},{ch.cmax!r},{ch.primary!r},"
                         f"{ch.secondary!r},{ch.ps or 'P'}")
        for i, ch in enumerate(self.digital, 1):
            lines.append(f"{i},{_clean(ch.name)},{_clean(ch.phase)},{_clean(ch.circuit)},{ch.normal}")
        lines.append(f"{self.line_frequency if self.line_frequency is not None else 50}")
        lines.append(str(len(rates)))
        lines += [f"{r!r},{int(n)}" for r, n in rates]
        # the package needs some date; the sample times are ours (rates or DAT stamps)
        fallback = Stamp(1970, 1, 1, 0, 0, 0, "000000")
        for stamp in (self.start, self.trigger):
            lines.append((stamp or fallback).cfg_text(month_first=rev == "1991"))
        lines.append(self.file_type)
        if rev != "1991":
            lines.append("1.0")  # time stamps are scaled by us, not by the package
        return "\n".join(lines) + "\n"


def _clean(text: str) -> str:
    return text.replace(",", ";").strip()


def parse_time_code(code: str) -> int | None:
    """Minutes east of UTC of a C37.111-2013 time code (``-5h30``, ``+1``, ``0``); None if absent."""
    code = (code or "").strip()
    m = _TIME_CODE.match(code)
    if not m:
        return None
    minutes = int(m.group(2)) * 60 + int(m.group(3) or 0)
    return -minutes if m.group(1) == "-" else minutes


def _fields(line: str) -> list[str]:
    parts = [p.strip() for p in line.split(",")]
    while len(parts) > 1 and parts[-1] == "":
        parts.pop()
    return parts


def _number(text: str, what: str, name: str, lineno: int, default: float | None = None) -> float:
    text = text.strip()
    if text == "" and default is not None:
        return default
    try:
        value = float(text.replace("D", "E").replace("d", "e"))
    except ValueError:
        raise CaptureError(f"{name}, line {lineno}: {what} '{text}' is not a number") from None
    if not math.isfinite(value):
        raise CaptureError(f"{name}, line {lineno}: {what} '{text}' is not a finite number")
    return value


def _count(text: str, suffix: str, name: str, lineno: int) -> int:
    t = text.strip().upper()
    if suffix and t.endswith(suffix):
        t = t[:-1].strip()
    if not t.isdigit():
        raise CaptureError(f"{name}, line {lineno}: channel count '{text.strip()}' is not a whole number")
    return int(t)


def parse_stamp(text: str, *, month_first: bool, name: str, what: str, warnings: list) -> Stamp | None:
    """Read ``dd/mm/yyyy,hh:mm:ss.ffffff`` (``mm/dd/yy`` in 1991); None when blank or unreadable."""
    parts = _fields(text)
    if len(parts) < 2 or not parts[0] and not parts[1]:
        warnings.append(f"the {what} time is missing from the header")
        return None
    dm, tm = _DATE.match(parts[0]), _TIME.match(parts[1].replace(" ", ""))
    if not dm or not tm:
        warnings.append(f"the {what} time '{text.strip()}' is not a date and time; it is ignored")
        return None
    a, b, year = int(dm.group(1)), int(dm.group(2)), int(dm.group(3))
    month, day = (a, b) if month_first else (b, a)
    if not 1 <= month <= 12 and 1 <= day <= 12:
        month, day = day, month
        warnings.append(f"the {what} date '{parts[0]}' only makes sense as "
                        f"{'day/month' if month_first else 'month/day'}; read that way")
    if len(dm.group(3)) <= 2:
        year += 2000 if year < 70 else 1900
        warnings.append(f"the {what} date has a 2-digit year; read as {year}")
    hour, minute, second = int(tm.group(1)), int(tm.group(2)), int(tm.group(3))
    if not (1 <= month <= 12 and 1 <= day <= 31 and hour < 24 and minute < 60 and second < 61):
        warnings.append(f"the {what} time '{text.strip()}' is not a valid date and time; it is ignored")
        return None
    return Stamp(year, month, day, hour, minute, min(second, 59), tm.group(4) or "")


def parse_header(text: str, *, name: str) -> Header:
    """Parse CFG text. Raises CaptureError naming ``name`` and the line when it cannot be read."""
    warnings: list = []
    raw = text.replace("\x1a", "").splitlines()
    numbered = [(i + 1, ln.strip()) for i, ln in enumerate(raw)]
    while numbered and not numbered[-1][1]:
        numbered.pop()
    blanks = [n for n, ln in numbered if not ln]
    if blanks:
        warnings.append(f"{len(blanks)} blank line(s) in the header were skipped")
    lines = [(n, ln) for n, ln in numbered if ln]
    if "\x1a" in text:
        warnings.append("Ctrl-Z padding after the header was ignored")
    pos = 0

    def take(what: str) -> tuple[int, str]:
        nonlocal pos
        if pos >= len(lines):
            raise CaptureError(f"{name}: the header ends before {what} (is the file cut short?)")
        pos += 1
        return lines[pos - 1]

    if not lines:
        raise CaptureError(f"{name}: the header file is empty")
    n, line = take("the station line")
    f = [p.strip() for p in line.split(",")]
    station = f[0]
    device = f[1] if len(f) > 1 else ""
    revision = ""
    if len(f) >= 3 and f[2].strip():
        revision = f[-1].strip() if len(f) > 3 and f[-1].strip().isdigit() else f[2].strip()
        if revision not in STANDARD_REVISIONS:
            warnings.append(f"the revision year '{revision}' is not a COMTRADE revision; the header "
                            "was read by its layout")
    n, line = take("the channel counts")
    f = _fields(line)
    if len(f) < 3:
        raise CaptureError(f"{name}, line {n}: expected the channel counts 'total,##A,##D', got '{line}'")
    total = _count(f[0], "", name, n)
    counts = {}
    for part in f[1:3]:
        key = part.strip().upper()[-1:]
        if key not in "AD" or key in counts:
            raise CaptureError(f"{name}, line {n}: expected the channel counts 'total,##A,##D', got '{line}'")
        counts[key] = _count(part, key, name, n)
    n_analog, n_digital = counts["A"], counts["D"]
    if total != n_analog + n_digital:
        warnings.append(f"the header says {total} channels but lists {n_analog} analog and "
                        f"{n_digital} digital")
    analog = []
    for k in range(n_analog):
        n, line = take(f"analog channel {k + 1} of {n_analog}")
        f = _fields(line)
        if 6 <= len(f) < 10:  # the range fields are missing: the defaults stand in
            f = f + [""] * (10 - len(f))
        if len(f) < 10:
            raise CaptureError(f"{name}, line {n}: analog channel {k + 1} has {len(f)} fields, expected 10 "
                               f"(1991) or 13: '{line[:80]}'")
        a = _number(f[5], f"the multiplier of analog channel {k + 1}", name, n)
        ch = AnalogChannel(k + 1, f[1], f[2], f[3], f[4], a,
                           _number(f[6], "the offset", name, n, 0.0),
                           _number(f[7], "the skew", name, n, 0.0),
                           _number(f[8], "the minimum", name, n, -32767.0),
                           _number(f[9], "the maximum", name, n, 32767.0))
        if len(f) >= 12:
            ch.primary = _number(f[10], "the primary ratio", name, n, 1.0)
            ch.secondary = _number(f[11], "the secondary ratio", name, n, 1.0)
            ch.ps = (f[12] if len(f) > 12 else "P") or "P"
        analog.append(ch)
    digital = []
    for k in range(n_digital):
        n, line = take(f"digital channel {k + 1} of {n_digital}")
        f = _fields(line)
        if len(f) == 3:  # 1991: n,name,normal
            digital.append(DigitalChannel(k + 1, f[1], normal=_state(f[2])))
        elif len(f) >= 2:
            f = f + [""] * (5 - len(f))
            digital.append(DigitalChannel(k + 1, f[1], f[2], f[3], _state(f[4])))
        else:
            raise CaptureError(f"{name}, line {n}: digital channel {k + 1} is '{line[:80]}', expected "
                               "'n,name,phase,circuit,state'")
    n, line = take("the line frequency")
    freq = None
    if "," in line or "/" in line:
        raise CaptureError(f"{name}, line {n}: expected the line frequency, got '{line[:80]}'; "
                           "the channel list may be shorter than the counts say")
    freq = _number(line, "the line frequency", name, n)
    n, line = take("the number of sampling rates")
    if not line.strip().isdigit():
        raise CaptureError(f"{name}, line {n}: the number of sampling rates '{line}' is not a whole number")
    nrates = int(line)
    rates = []
    for k in range(max(nrates, 1)):
        n, line = take(f"sampling rate {k + 1} of {max(nrates, 1)}")
        f = _fields(line)
        if len(f) != 2:
            raise CaptureError(f"{name}, line {n}: sampling rate {k + 1} is '{line}', expected 'rate,last sample'")
        rate = _number(f[0], "the sampling rate", name, n)
        last = _number(f[1], "the last sample number", name, n)
        if last != int(last) or last < 0:
            raise CaptureError(f"{name}, line {n}: the last sample number '{f[1]}' is not a whole number")
        if rate < 0 or rate > 1e10 or 0 < rate < 1e-3:
            raise CaptureError(f"{name}, line {n}: the sampling rate {f[0]} Hz is not a plausible rate")
        rates.append((rate, int(last)))
    if nrates > 0 and any(r == 0 for r, _ in rates):
        warnings.append("a sampling rate of 0 was given; the rate is taken from the time stamps")
        nrates = 0
        rates = [(0.0, rates[-1][1])]
    month_first = revision in ("1991", "")
    n, line = take("the time of the first sample")
    start = parse_stamp(line, month_first=month_first, name=name, what="first sample", warnings=warnings)
    n, line = take("the trigger time")
    trigger = parse_stamp(line, month_first=month_first, name=name, what="trigger", warnings=warnings)
    n, line = take("the data file type (ASCII or BINARY)")
    ft = line.strip().upper()
    if ft not in FILE_TYPES:
        raise CaptureError(f"{name}, line {n}: data file type '{line.strip()}' is not one of "
                           f"{', '.join(FILE_TYPES)}")
    mult = 1.0
    time_code = local_code = ""
    if pos < len(lines):
        n, line = take("the time multiplier")
        mult = _number(line, "the time multiplier", name, n)
        if mult <= 0:
            warnings.append(f"the time multiplier {line} is not positive; 1 is used")
            mult = 1.0
    if pos < len(lines):
        n, line = take("the time codes")
        f = _fields(line) + [""]
        time_code, local_code = f[0], f[1]
    for stamp, what in ((start, "first sample"), (trigger, "trigger")):
        if stamp is not None and stamp.year == 1970 and stamp.month == 1 and stamp.day == 1:
            warnings.append(f"the {what} date is 1970-01-01, which looks like an unset clock")
    return Header(name=name, station=station, device=device, revision=revision, analog=analog,
                  digital=digital, line_frequency=freq, nrates=nrates, rates=rates, start=start,
                  trigger=trigger, file_type=ft, time_multiplier=mult, time_code=time_code,
                  local_code=local_code, warnings=warnings)


def _state(text: str) -> int:
    return 1 if text.strip() == "1" else 0
