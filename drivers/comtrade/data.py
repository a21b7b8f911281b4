"""The DAT part of a COMTRADE record, normalised before the ``comtrade`` package reads it.

ASCII: blank lines, Ctrl-Z, trailing separators and spaces, CRLF, empty time stamps and a cut
last line are repaired. Binary: Ctrl-Z padding and a partial last record are cut off. Both
report the records actually present, their sample numbers and raw time stamps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from drivers.capture import CaptureError

from .header import Header

MISSING_STAMP = 0xFFFFFFFF
ANALOG_BYTES = {"BINARY": 2, "BINARY32": 4, "FLOAT32": 4}


@dataclass
class DataRows:
    payload: str | bytes  # what the comtrade package reads
    records: int
    sample_numbers: np.ndarray
    stamps: np.ndarray  # raw time stamps, NaN where missing
    warnings: list = field(default_factory=list)


def record_size(header: Header) -> int:
    """Bytes per binary record: sample number, time stamp, analog values, 16-bit status words."""
    return 8 + len(header.analog) * ANALOG_BYTES[header.file_type] + 2 * math.ceil(len(header.digital) / 16)


def read_binary(data: bytes, header: Header, name: str) -> DataRows:
    warnings = []
    size = record_size(header)
    n, rest = divmod(len(data), size)
    tail = data[n * size:]
    if rest:
        if set(tail) <= {0x1A, 0x00, 0x0D, 0x0A}:
            warnings.append(f"{rest} padding byte(s) (Ctrl-Z) after the last record were ignored")
        else:
            warnings.append(f"the last record is cut short ({rest} of {size} bytes); it was dropped")
    while n > 0 and set(data[(n - 1) * size:n * size]) == {0x1A}:
        n -= 1
        warnings.append("a record made of Ctrl-Z padding bytes was ignored")
    body = data[:n * size]
    head = np.frombuffer(body, dtype=np.dtype([("n", "<u4"), ("t", "<u4"), ("rest", f"V{size - 8}")]),
                         count=n) if n else np.zeros(0, dtype=[("n", "<u4"), ("t", "<u4")])
    stamps = head["t"].astype(float)
    stamps[head["t"] == MISSING_STAMP] = np.nan
    return DataRows(body, n, head["n"].astype(np.int64), stamps, warnings)


def read_ascii(data: bytes, header: Header, name: str) -> DataRows:
    warnings = []
    text = data.decode("latin-1")  # numbers only; this never fails
    if "\x1a" in text:
        text = text.replace("\x1a", "")
        warnings.append("Ctrl-Z padding in the data file was ignored")
    n_a, n_d = len(header.analog), len(header.digital)
    expected = 2 + n_a + n_d
    rows, linenos = [], []
    blanks = trailing = 0
    lines = text.splitlines()
    last = len(lines)
    while last > 0 and not lines[last - 1].strip():
        last -= 1
    for i in range(last):
        s = lines[i].strip()
        if not s:
            blanks += 1
            continue
        f = [p.strip() for p in s.split(",")]
        if len(f) > expected and not any(f[expected:]):
            del f[expected:]
            trailing += 1
        if len(f) != expected:
            if i == last - 1 and len(f) < expected:
                warnings.append(f"the last line ({i + 1}) is cut short ({len(f)} of {expected} values); "
                                "it was dropped")
                break
            raise CaptureError(f"{name}, line {i + 1}: {len(f)} values where the header declares {expected} "
                               f"(sample number, time stamp, {n_a} analog, {n_d} digital)")
        rows.append(f)
        linenos.append(i + 1)
    if blanks:
        warnings.append(f"{blanks} blank line(s) in the data file were skipped")
    if trailing:
        warnings.append(f"a trailing separator after {trailing} data line(s) was ignored")
    n = len(rows)
    if n == 0:
        return DataRows("", 0, np.zeros(0, np.int64), np.zeros(0), warnings)
    table = np.array(rows, dtype=object)
    numbers = _column(table[:, 0], "the sample number", name, linenos)
    stamp_text = table[:, 1]
    empty = stamp_text == ""
    stamps = np.full(n, np.nan)
    if not empty.all():
        stamps[~empty] = _column(stamp_text[~empty], "the time stamp", name, np.asarray(linenos)[~empty])
    stamps[stamps == MISSING_STAMP] = np.nan
    missing_marker = "" if header.standard_revision == "1991" else "99999"
    analog_out = []
    for k in range(n_a):
        col = table[:, 2 + k]
        blank = col == ""
        if blank.any():
            warnings.append(f"analog channel '{header.analog[k].name}' has {int(blank.sum())} empty value(s), "
                            "read as missing")
            col = np.where(blank, missing_marker, col)
        ok = col != missing_marker
        _column(col[ok], f"the value of '{header.analog[k].name}'", name, np.asarray(linenos)[ok])
        analog_out.append(col)
    digital_out = []
    for k in range(n_d):
        col = table[:, 2 + n_a + k]
        values = _column(np.where(col == "", "0", col), f"the state of '{header.digital[k].name}'", name, linenos)
        digital_out.append(np.where(values != 0, "1", "0"))
    seq = np.arange(1, n + 1).astype(str)
    cols = [seq, np.where(empty, "", stamp_text)] + analog_out + digital_out
    payload = "\n".join(",".join(r) for r in zip(*cols))
    return DataRows(payload, n, numbers.astype(np.int64), stamps, warnings)


def _column(values, what: str, name: str, linenos) -> np.ndarray:
    try:
        out = np.asarray(values, dtype=str).astype(float)
    except ValueError:
        for v, ln in zip(values, linenos):
            try:
                float(v)
            except ValueError:
                raise CaptureError(f"{name}, line {ln}: {what} '{v}' is not a number") from None
        raise CaptureError(f"{name}: {what} holds values that are not numbers") from None
    bad = ~np.isfinite(out)
    if bad.any():
        ln = np.asarray(linenos)[np.argmax(bad)]
        raise CaptureError(f"{name}, line {ln}: {what} is not a finite number")
    return out
