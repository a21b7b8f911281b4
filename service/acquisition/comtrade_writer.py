"""Writing captures as IEEE C37.111-2013 COMTRADE (.cfg + .dat, and a free-text .hdr).

Formats: ASCII, BINARY (int16), BINARY32 (int32), FLOAT32. Channels: ``travel`` [rad] and
``vibration`` [g], then each recorded channel of ``Capture.aux`` (an analyser's coil currents,
travel as recorded, DCRM) as ``aux <name>`` in its own unit, listed with its kind and unit in
the .hdr (``drivers.capture_file`` reads them back); each channel scaled ``value = a·code + b`` over the sensor range (or the data range where
the data exceed it), so a clipped channel reads as sitting at its limits. Time stamps are in µs
(timemult 1), but readers must use the sample-rate line, as the standard requires.

Durability: each file is written to a temporary name, flushed and fsynced, renamed into place
(.hdr, then .dat, then .cfg last, so a visible .cfg means a complete record), and the directory
is fsynced. Only then does ``write_comtrade`` return.
"""

from __future__ import annotations

import json
import math
import os
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

from drivers.capture import Capture
from drivers.capture_file import AUX_PREFIX
from service.durable import fsync_dir, write_durably

FORMATS = ("ASCII", "BINARY", "BINARY32", "FLOAT32")
_INT_MAX = {"ASCII": 32767, "BINARY": 32767, "BINARY32": 2_147_483_647}
_UNKNOWN_START = datetime(1970, 1, 1, tzinfo=timezone.utc)


def write_comtrade(capture: Capture, directory: str | Path, name: str, *, format: str = "BINARY",
                   rev: int = 2013, station: str = "hvcb", device: str = "hvcb-daq",
                   frequency_hz: float = 50.0) -> Path:
    """Write ``capture`` as ``directory/name.cfg`` + ``.dat`` (+ ``.hdr``); returns the .cfg path.

    Parameters
    ----------
    capture : Capture
        Travel [rad] and, when present, vibration [g].
    directory : path
        Created if missing.
    name : str
        File stem (no directory separators).
    format : {"BINARY", "ASCII", "BINARY32", "FLOAT32"}
    rev : {1999, 2013}
        Revision year written in the .cfg.
    station, device : str
        Station name and recording device id (first .cfg line).
    frequency_hz : float
        Line frequency [Hz] (a required .cfg field; irrelevant to a mechanism).
    """
    fmt = str(format).upper()
    if fmt not in FORMATS:
        raise ValueError(f"COMTRADE format must be one of {', '.join(FORMATS)}, got {format!r}")
    if rev not in (1999, 2013):
        raise ValueError(f"COMTRADE revision must be 1999 or 2013, got {rev}")
    if not name or any(sep in name for sep in ("/", "\\", os.sep)):
        raise ValueError(f"capture name must be a plain file stem, got {name!r}")
    channels = [("travel", "rad", np.asarray(capture.travel, dtype=float), capture.travel_limits)]
    if capture.vibration is not None:
        channels.append(("vibration", "g", np.asarray(capture.vibration, dtype=float),
                         capture.vibration_limits))
    channels += [(f"{AUX_PREFIX}{x.name}", _ascii_unit(x.unit), np.asarray(x.data, dtype=float), None)
                 for x in capture.aux]
    n = channels[0][2].size
    if n == 0:
        raise ValueError("cannot write an empty capture")
    for ch_name, _, values, _ in channels:
        if not np.all(np.isfinite(values)):
            raise ValueError(f"the {ch_name} channel has NaN or infinite samples; COMTRADE cannot hold them")
    fs = float(capture.sample_rate)
    if not (math.isfinite(fs) and fs > 0):
        raise ValueError(f"sample rate must be positive, got {fs} Hz")
    stamps_us = np.round(np.arange(n) * (1e6 / fs))
    timemult = 1.0
    while stamps_us[-1] / timemult > 4_294_967_295:  # the .dat time stamp is a uint32
        timemult *= 10.0
    stamps = np.round(stamps_us / timemult).astype(np.int64)

    scaled = [_scale(values, limits, fmt) for _, _, values, limits in channels]
    start = capture.start_time or _UNKNOWN_START
    trigger = start
    window = capture.meta.get("window_start_s") if capture.meta else None
    if window is not None and math.isfinite(window):
        trigger = start + timedelta(seconds=float(window))

    lines = [f"{_field(station)},{_field(device)},{rev}",
             f"{len(channels)},{len(channels)}A,0D"]
    for i, ((ch_name, unit, _, _), (a, b, _, lo, hi)) in enumerate(zip(channels, scaled), start=1):
        lines.append(f"{i},{ch_name},,,{unit},{a:.12e},{b:.12e},0,{_num(lo)},{_num(hi)},1,1,P")
    lines += [f"{frequency_hz:g}", "1", f"{fs:.10g},{n}", _stamp(start), _stamp(trigger), fmt,
              f"{timemult:g}"]
    if rev == 2013:
        lines += ["0,0", "0,0"]
    cfg_text = "\r\n".join(lines) + "\r\n"
    dat_bytes = _dat(stamps, [codes for _, _, codes, _, _ in scaled], fmt)
    hdr_text = json.dumps(_header(capture), indent=1, default=str) + "\n"

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    cfg_path = directory / f"{name}.cfg"
    for suffix, data in ((".hdr", hdr_text.encode()), (".dat", dat_bytes), (".cfg", cfg_text.encode("ascii"))):
        write_durably(directory / f"{name}{suffix}", data, sync_dir=False)
    fsync_dir(directory)  # once for the three renames
    return cfg_path


def _scale(values: np.ndarray, limits, fmt: str):
    """(a, b, codes, cmin, cmax) for one channel."""
    lo, hi = float(values.min()), float(values.max())
    if limits is not None and all(math.isfinite(x) for x in limits):
        lo, hi = min(lo, float(limits[0])), max(hi, float(limits[1]))
    if fmt == "FLOAT32":
        return 1.0, 0.0, values.astype("<f4"), lo, hi
    top = _INT_MAX[fmt]
    if hi <= lo:  # a constant channel still needs a non-zero gain
        hi = lo + 1.0
    a = (hi - lo) / (2 * top)
    b = (hi + lo) / 2
    codes = np.clip(np.round((values - b) / a), -top, top).astype(np.int64)
    return a, b, codes, -top, top


def _dat(stamps: np.ndarray, codes: list, fmt: str) -> bytes:
    n = stamps.size
    if fmt == "ASCII":
        cols = [np.arange(1, n + 1), stamps, *codes]
        table = np.column_stack(cols).astype(np.int64)
        return ("\r\n".join(",".join(map(str, row)) for row in table.tolist()) + "\r\n").encode("ascii")
    analog = {"BINARY": "<i2", "BINARY32": "<i4", "FLOAT32": "<f4"}[fmt]
    dtype = np.dtype([("n", "<u4"), ("t", "<u4")] + [(f"a{i}", analog) for i in range(len(codes))])
    rec = np.empty(n, dtype=dtype)
    rec["n"] = np.arange(1, n + 1)
    rec["t"] = stamps
    for i, c in enumerate(codes):
        rec[f"a{i}"] = c
    return rec.tobytes()


def stored_analyser_results(cfg_path) -> dict | None:
    """The analyser header (profile, metadata, results) kept in a stored capture's .hdr, if any."""
    hdr = Path(cfg_path).with_suffix(".hdr")
    try:
        meta = json.loads(hdr.read_text()).get("meta") or {}
    except (OSError, ValueError, AttributeError):
        return None
    found = meta.get("analyser") if isinstance(meta, dict) else None
    return found if isinstance(found, dict) else None


def stored_masked_spans(cfg_path) -> list:
    """The over-range spans (``drivers.masked``) kept in a stored capture's .hdr; [] if none."""
    hdr = Path(cfg_path).with_suffix(".hdr")
    try:
        meta = json.loads(hdr.read_text()).get("meta") or {}
    except (OSError, ValueError, AttributeError):
        return []
    found = meta.get("masked") if isinstance(meta, dict) else None
    return [s for s in found if isinstance(s, dict)] if isinstance(found, list) else []


def _header(capture: Capture) -> dict:
    """Free-text .hdr content: what the .cfg cannot say (flags, window, stream position, the
    recorded channels' kinds and units)."""
    return {"source": capture.source, "flags": list(capture.flags),
            "first_sample_index": int(capture.first_sample_index), "meta": capture.meta,
            "aux": [{"name": x.name, "kind": x.kind, "unit": x.unit} for x in capture.aux]}


def _ascii_unit(unit: str) -> str:
    """A unit as the .cfg (ASCII) can hold it: µΩ -> uOhm; the .hdr keeps the real one."""
    return unit.replace("µ", "u").replace("μ", "u").replace("Ω", "Ohm").encode("ascii", "replace").decode()


def _stamp(t: datetime) -> str:
    if t.tzinfo is not None:
        t = t.astimezone(timezone.utc)
    return t.strftime("%d/%m/%Y,%H:%M:%S.%f")


def _field(text: str) -> str:
    return str(text).replace(",", " ").replace("\n", " ").replace("\r", " ")


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else f"{x:.9g}"
