"""A COMTRADE record read from what the field writes: a thin normalising layer in front of the
``comtrade`` package.

The layer decodes the text (UTF-8 or a legacy code page), reads the header leniently, cleans
the data file and counts the records actually present, then hands a canonical header and the
clean data to the package for the channel values (a·x+b). Sample times come from the header's
rate sections, or from the time stamps when it gives none.
"""

from __future__ import annotations

import warnings as _warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drivers.capture import CaptureError

from .combined import split_cff
from .data import read_ascii, read_binary
from .header import Header, parse_header
from .text import decode_text

UNIFORM_TOLERANCE = 0.01  # relative spread of the sample interval still called uniform


@dataclass
class Record:
    """One COMTRADE record in engineering units.

    Attributes
    ----------
    time : ndarray
        Sample times from the first sample [s].
    analog : list of ndarray
        Channel values a·x+b, NaN where a sample is missing.
    digital : list of ndarray
        0/1 states.
    sample_rate : float
        [Hz]: the header's rate; the mean rate over several rate sections; or 1/median interval
        of the time stamps when the header gives none.
    rate_source : str
        ``header`` or ``time stamps``.
    uniform : bool
        Whether the samples are equally spaced (one rate section, or regular time stamps).
    """

    name: str
    header: Header
    encoding: str
    time: np.ndarray
    analog: list
    digital: list
    sample_rate: float
    rate_source: str
    uniform: bool
    hdr_text: str | None = None
    hdr_encoding: str | None = None
    inf_text: str | None = None
    inf_encoding: str | None = None
    container: str = "CFG+DAT"
    warnings: list = field(default_factory=list)

    @property
    def samples(self) -> int:
        return int(self.time.size)

    @property
    def analog_names(self) -> list:
        return [ch.name for ch in self.header.analog]

    def uniform_channel(self, index: int) -> np.ndarray:
        """An analog channel on an equally spaced grid at ``sample_rate`` (interpolated when the
        record is not uniformly sampled)."""
        x = np.asarray(self.analog[index], float)
        if self.uniform:
            return x
        grid = np.arange(self.samples) / self.sample_rate
        return np.interp(grid, self.time, x)


def find_sibling(path: Path, suffix: str) -> Path | None:
    """``path`` with another extension, in any letter case (``4.CFG`` -> ``4.DAT``)."""
    for cand in (path.with_suffix(suffix.lower()), path.with_suffix(suffix.upper())):
        if cand.is_file():
            return cand
    if path.parent.is_dir():
        for cand in path.parent.iterdir():
            if cand.stem == path.stem and cand.suffix.lower() == suffix.lower() and cand.is_file():
                return cand
    return None


def read_record(path: str | Path, *, encoding: str | None = None) -> Record:
    """Read a ``.cfg`` (with its ``.dat`` and any ``.hdr``/``.inf``), a ``.dat`` or a ``.cff``.

    ``encoding`` forces the code page of the text files. Raises CaptureError naming the file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".dat":
        cfg = find_sibling(path, ".cfg")
        if cfg is None:
            raise CaptureError(f"{path}: no header file {path.stem}.cfg next to the data file")
        path, suffix = cfg, ".cfg"
    if not path.is_file():
        raise CaptureError(f"capture file not found: {path}")
    if suffix == ".cff":
        return read_cff_bytes(_read(path), name=str(path), encoding=encoding)
    if suffix != ".cfg":
        raise CaptureError(f"{path}: not a COMTRADE file (expected .cfg, .dat or .cff)")
    dat = find_sibling(path, ".dat")
    if dat is None:
        raise CaptureError(f"COMTRADE data file missing next to {path} (expected {path.stem}.dat)")
    hdr, inf = find_sibling(path, ".hdr"), find_sibling(path, ".inf")
    return read_record_bytes(_read(path), _read(dat), name=str(path), dat_name=str(dat), encoding=encoding,
                             hdr=_read(hdr) if hdr else None, inf=_read(inf) if inf else None)


def _read(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except OSError as exc:
        raise CaptureError(f"{path}: cannot be read ({exc.strerror or 'input/output error'})") from None


def read_cff_bytes(data: bytes, *, name: str, encoding: str | None = None) -> Record:
    """Read a CFF held in memory. ``name`` names the file in messages."""
    try:
        sections, fmt, notes = split_cff(data, name)
    except CaptureError as exc:
        raise CaptureError(f"malformed COMTRADE {exc}") from None
    rec = read_record_bytes(sections["CFG"], sections["DAT"], name=name, dat_name=f"{name} (DAT section)",
                            encoding=encoding, hdr=sections.get("HDR"), inf=sections.get("INF"),
                            dat_format=fmt, notes=notes)
    rec.container = "CFF"
    return rec


def read_record_bytes(cfg: bytes, dat: bytes, *, name: str, dat_name: str | None = None,
                      encoding: str | None = None, hdr: bytes | None = None, inf: bytes | None = None,
                      dat_format: str | None = None, notes: list | None = None) -> Record:
    """Read a record held in memory. ``name`` names the header in messages.

    Raises CaptureError ``malformed COMTRADE <file>[, line N]: <what is wrong>``.
    """
    try:
        return _read_record_bytes(cfg, dat, name=name, dat_name=dat_name, encoding=encoding, hdr=hdr,
                                  inf=inf, dat_format=dat_format, notes=notes)
    except CaptureError as exc:
        raise CaptureError(f"malformed COMTRADE {exc}") from None


def _read_record_bytes(cfg, dat, *, name, dat_name, encoding, hdr, inf, dat_format, notes) -> Record:
    dat_name = dat_name or name
    notes = list(notes or [])
    text, enc = decode_text(cfg, name=name, encoding=encoding)
    header = parse_header(text, name=name)
    notes += header.warnings
    if enc not in ("ascii", "utf-8") and not encoding:
        notes.append(f"the header is not UTF-8; its text was read as {enc}")
    if dat_format and dat_format != header.file_type:
        notes.append(f"the CFF marks the data {dat_format} but the header says {header.file_type}; "
                     f"read as {header.file_type}")
    rows = read_ascii(dat, header, dat_name) if header.file_type == "ASCII" else read_binary(dat, header, dat_name)
    notes += rows.warnings
    n, declared = rows.records, header.declared_samples
    if n == 0:
        raise CaptureError(f"{dat_name}: the data file holds no complete record"
                           + (f" (the header declares {declared})" if declared else ""))
    if n < declared:
        notes.append(f"the data file holds {n} of the {declared} samples the header declares "
                     "(truncated file); the samples present were read")
    elif n == declared + 1:
        notes.append(f"the data file holds one record more than the {declared} the header declares; "
                     "it was read")
    elif n > declared:
        notes.append(f"the data file holds {n} records, the header declares {declared}; all were read")
    if rows.sample_numbers.size and rows.sample_numbers[0] == 0:
        notes.append("the sample numbers start at 0, not 1")
    time, rate, source, uniform = _sample_times(header, rows.stamps, n, name, notes)
    values = _channel_values(header, rows.payload, rate, n, dat_name)
    analog = [np.asarray(v, float)[:n] for v in values.analog]
    digital = [np.asarray(v, np.int8)[:n] for v in values.status]
    for ch, x in zip(header.analog, analog):
        missing = int(np.count_nonzero(~np.isfinite(x)))
        if missing:
            notes.append(f"analog channel '{ch.name}' has {missing} missing sample(s)")
    rec = Record(name=name, header=header, encoding=enc, time=time, analog=analog, digital=digital,
                 sample_rate=rate, rate_source=source, uniform=uniform, warnings=notes)
    for kind, blob in (("hdr", hdr), ("inf", inf)):
        if blob is not None and blob.strip(b"\x1a\r\n\t "):
            t, e = decode_text(blob, name=f"{name} ({kind.upper()})", encoding=None)
            setattr(rec, f"{kind}_text", t.replace("\x1a", ""))
            setattr(rec, f"{kind}_encoding", e)
    return rec


def _sample_times(header: Header, stamps: np.ndarray, n: int, name: str, notes: list):
    """``(time [s], rate [Hz], source, uniform)``."""
    if header.nrates > 0:
        bounds = [last for _, last in header.rates]
        rates = [r for r, _ in header.rates]
        # the rate of each sample by its position (1-based), the last rate beyond the last section
        pos = np.arange(1, n + 1)
        section = np.minimum(np.searchsorted(bounds, pos, side="left"), len(rates) - 1)
        period = 1.0 / np.asarray(rates)[section]
        time = np.concatenate([[0.0], np.cumsum(period[1:])])
        counts = np.diff([0] + bounds)
        if len(rates) == 1:
            rate = rates[0]
        else:
            rate = float(np.sum(counts)) / float(np.sum(counts / np.asarray(rates)))
            notes.append(f"{len(rates)} sampling-rate sections ({min(rates):g}-{max(rates):g} Hz); "
                         f"the mean rate is {rate:.6g} Hz")
        uniform = len(set(rates)) == 1
        return time, float(rate), "header", uniform
    t = stamps * header.time_base * header.time_multiplier
    ok = np.isfinite(t)
    if ok.sum() < 2:
        raise CaptureError(f"{name}: the header gives no sampling rate (nrates = 0) and the data file has "
                           "too few time stamps to take it from")
    idx = np.flatnonzero(ok)
    dt = np.diff(t[idx]) / np.diff(idx)
    # the mean interval: stamps are quantised (1249/1250 µs), so the span is the best estimate
    period = float((t[idx[-1]] - t[idx[0]]) / (idx[-1] - idx[0]))
    if not period > 0:
        raise CaptureError(f"{name}: the header gives no sampling rate and the time stamps do not increase")
    if (~ok).any():
        notes.append(f"{int((~ok).sum())} missing time stamp(s) were interpolated")
    time = np.interp(np.arange(n), idx, t[idx], left=np.nan)
    lead = np.isnan(time)  # samples before the first stamp: one period apart
    time[lead] = t[idx[0]] - (idx[0] - np.flatnonzero(lead)) * period
    time -= time[0]
    uniform = bool(np.max(np.abs(dt - period)) <= UNIFORM_TOLERANCE * period)
    notes.append(f"the header gives no sampling rate; {1 / period:.6g} Hz was taken from the time stamps")
    if not uniform:
        notes.append("the time stamps are not equally spaced; the samples are placed at their time stamps")
    return time, 1.0 / period, "time stamps", uniform


# The raw value that marks a missing analog sample (0x8000…); raw -1 in 1991 data is a value
# (see Header.canonical_text), and FLOAT32 has no marker.
_MISSING = {"BINARY": -32768, "BINARY32": -2147483648, "FLOAT32": None}
_RAW_TYPE = {"BINARY": "<i2", "BINARY32": "<i4", "FLOAT32": "<f4"}


def _channel_values(header: Header, payload, rate: float, n: int, dat_name: str):
    if header.file_type in _RAW_TYPE:
        return _binary_values(header, payload, n)
    return _package_values(header, payload, rate, n, dat_name)


def _binary_values(header: Header, payload: bytes, n: int):
    """The binary layouts decoded column by column, as the comtrade package does; the package
    also works out a time per sample in Python, which this layer takes from the header instead
    (5–9 ms of a 10 k-sample capture)."""
    raw = _RAW_TYPE[header.file_type]
    n_a, n_words = len(header.analog), -(-len(header.digital) // 16)
    fields = [("n", "<u4"), ("t", "<u4")] + [(f"a{k}", raw) for k in range(n_a)] \
        + [(f"d{k}", "<u2") for k in range(n_words)]
    rows = np.frombuffer(payload, dtype=np.dtype(fields), count=n)
    missing = _MISSING[header.file_type]
    analog = []
    for k, ch in enumerate(header.analog):
        y = rows[f"a{k}"].astype(np.float64)
        v = ch.a * y + ch.b
        if missing is not None:
            v[y == missing] = np.nan
        analog.append(v)
    status = [(rows[f"d{k // 16}"].astype(np.int64) >> (k % 16)) & 1 for k in range(len(header.digital))]
    return _Values(analog, status)


def _package_values(header: Header, payload, rate: float, n: int, dat_name: str):
    import comtrade

    pkg = comtrade.Comtrade(use_numpy_arrays=True, use_double_precision=True, ignore_warnings=True)
    try:
        with _warnings.catch_warnings():
            _warnings.simplefilter("ignore")
            pkg.read(header.canonical_text([(rate, n)]), payload)
    except Exception:  # the package raises many types; the layer has already checked the input
        raise CaptureError(f"{dat_name}: the {header.file_type} data could not be decoded with the channel "
                           "layout the header gives") from None
    return _Values(pkg.analog, pkg.status)


@dataclass
class _Values:
    analog: list
    status: list
