"""Capture files to ``Capture``: COMTRADE (``.cfg``+``.dat`` or ``.cff``, through the tolerant
reader in ``drivers.comtrade``), breaker-analyser exports (``drivers.analyser``, recognised by
content) and CSV ``t_s,travel_rad[,vibration_g]``. This module is the one entry point: the CLI,
uploads, the jobs and the agent all read captures through it.

Outside names and units become ours here: the travel channel in rad, the vibration in g. What
the reader had to repair travels along in ``Capture.meta["warnings"]``.
"""

from __future__ import annotations

from dataclasses import replace

import io
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

from drivers.capture import AuxChannel, Capture, CaptureError
from drivers.analyser import TRAVEL, looks_like_analyser, parse_analyser
from drivers.comtrade import Record, decode_text, read_cff_bytes, read_record, read_record_bytes
from drivers.masked import filled

# Unit spellings accepted per quantity, with the factor to our unit.
TRAVEL_UNITS = {"rad": 1.0, "radian": 1.0, "radians": 1.0, "deg": np.pi / 180, "degree": np.pi / 180,
                "degrees": np.pi / 180, "°": np.pi / 180, "mrad": 1e-3}
# Temperature channel units -> (factor, offset) to Celsius.
TEMPERATURE_UNITS = {"c": (1.0, 0.0), "°c": (1.0, 0.0), "degc": (1.0, 0.0), "deg c": (1.0, 0.0),
                     "celsius": (1.0, 0.0), "k": (1.0, -273.15), "kelvin": (1.0, -273.15)}
# A temperature outside this is a sensor fault (or not a temperature) [C].
TEMPERATURE_PLAUSIBLE_C = (-60.0, 100.0)
VIBRATION_UNITS = {"g": 1.0, "gn": 1.0, "m/s2": 1 / 9.80665, "m/s^2": 1 / 9.80665, "m/s²": 1 / 9.80665}

MAX_SAMPLES = 50_000_000
# hvcb's own COMTRADE (service/acquisition/comtrade_writer.py) names a recorded channel kept
# beside the travel "aux <name>": never a breaker's travel or vibration channel name.
AUX_PREFIX = "aux "
OVER_RANGE_FLAG = "over-range samples"  # an operation's flag: its channels' masked sample counts


def read_capture(path: str | Path, *, travel_channel: str = "travel", vibration_channel: str = "vibration",
                 encoding: str | None = None, temperature_channel: str | None = None,
                 rate: float | None = None, to_rad=None) -> Capture:
    """Read a COMTRADE ``.cfg`` (with its ``.dat``), a ``.dat``, a ``.cff``, a breaker-analyser
    export, or a CSV ``t_s,travel_rad[,vibration_g]``.

    ``temperature_channel``: a COMTRADE channel with the ambient or mechanism temperature [C or
    K]; its median goes into ``meta["temperature_c"]``. ``rate`` [Hz] is the sampling rate of a
    bare analyser export (one without a header stating it). ``to_rad(values, unit, stated_stroke)``
    maps a travel recorded in mm to ours, returning ``(travel [rad from closed], info)`` with
    ``info`` JSON-able: the breaker's ``travel_map.to_rad`` (its file's ``[travel]`` section);
    without it an analyser export's mm travel is refused in words.

    Raises
    ------
    CaptureError
        Missing or malformed files, unknown channels, wrong units or NaN samples; the message
        names the file and says what is wrong.
    """
    path = Path(path)
    if not path.exists():
        raise CaptureError(f"capture file not found: {path}")
    if path.is_dir():
        raise CaptureError(f"{path} is a folder; give the capture's .cfg, .cff or .csv file")
    suffix = path.suffix.lower()
    if suffix in (".cfg", ".cff", ".dat"):
        return read_comtrade(path, travel_channel=travel_channel, vibration_channel=vibration_channel,
                             encoding=encoding, temperature_channel=temperature_channel)
    text, _ = read_csv_text(path, encoding=encoding) if suffix in (".csv", ".txt") else sniff_text(path, encoding)
    if text is not None and looks_like_analyser(text):
        return analyser_capture(text, source=str(path), travel_channel=travel_channel, rate=rate,
                                to_rad=to_rad)
    if suffix in (".csv", ".txt"):
        return parse_csv(text, source=str(path))
    raise CaptureError(f"{path}: unknown capture format '{path.suffix}'; give a COMTRADE .cfg/.cff, "
                       "an analyser export or a .csv")


def load_capture_bytes(data: bytes, *, name: str, travel_channel: str = "travel",
                       vibration_channel: str = "vibration", encoding: str | None = None,
                       rate: float | None = None, to_rad=None) -> Capture:
    """Read one uploaded text capture (an analyser export or a CSV) held in memory."""
    text, _ = decode_text(data, name=name, encoding=encoding)
    source = f"upload:{name}"
    if looks_like_analyser(text):
        return analyser_capture(text, source=source, travel_channel=travel_channel, rate=rate, to_rad=to_rad)
    return parse_csv(text, source=source)


def sniff_text(path: Path, encoding: str | None):
    """(text, encoding) of a file with an unknown suffix when it decodes as text, else (None, None)."""
    try:
        data = path.read_bytes()[:4_000_000]
    except OSError:
        return None, None
    if b"\0" in data[:4096]:
        return None, None
    try:
        text, enc = decode_text(data, name=str(path), encoding=encoding)
    except Exception:
        return None, None
    return text, enc


def analyser_capture(text: str, *, source: str, travel_channel: str = "travel", rate: float | None = None,
                     to_rad=None) -> Capture:
    """An analyser export as a Capture: the chosen contact travel mapped to rad by ``to_rad``,
    the other wired channels in ``aux`` (their own units), the header in ``meta["analyser"]``."""
    record = parse_analyser(text, source=source, rate=rate)
    travels = [c for c in record.channels if c.kind == TRAVEL]
    wanted = str(travel_channel).strip()
    warnings = list(record.warnings)
    if wanted.lower() == "travel":
        wired = [c for c in travels if c.wired]
        if not wired:
            dead = [c.name for c in travels if c.over_range_throughout]
            raise CaptureError(f"{source}: no contact-travel channel is wired (all read a constant"
                               + (f"; {', '.join(dead)} over-range throughout" if dead else "") + ")")
        # A phase with over-range samples is fitted only when every wired phase has some.
        clean = [c for c in wired if c.mask is None]
        chosen = clean[0] if clean else wired[0]
        if chosen is not wired[0]:
            warnings.append(f"travel {wired[0].name} has over-range samples; {chosen.name}, whose samples "
                            "are all valid, is fitted instead")
    else:
        matches = [c for c in travels if wanted.lower() in (c.name.lower(), c.column.lower())]
        if not matches:
            raise CaptureError(f"{source}: no travel channel named '{wanted}' (travel channels: "
                               f"{', '.join(c.name for c in travels)}); set [channels] travel in the breaker file")
        chosen = matches[0]
        if chosen.over_range_throughout:
            raise CaptureError(f"{source}: travel channel {chosen.name} is over-range throughout (every sample "
                               "reads ∞ or NaN): it holds no reading; fit another phase with [channels] travel")
        if not chosen.wired:
            raise CaptureError(f"{source}: travel channel {chosen.name} is not wired (it reads a constant)")
    if to_rad is None:
        raise CaptureError(f"{source}: the contact travel {chosen.name} is in mm; the breaker file's [travel] "
                           "section must map mm to the model's coordinate (config/breakers/generic-analyser.toml "
                           "serves a breaker of unknown design; see docs/breaker-file.md)")
    stated = record.stated_stroke_mm(chosen.name)
    # Over-range samples are carried filled (straight line between valid neighbours) and listed
    # in meta["masked"]: COMTRADE and the filters hold no NaN; the fit refuses a window they touch.
    try:
        travel, info = to_rad(_filled(chosen), chosen.unit, stated)
    except ValueError as exc:
        raise CaptureError(f"{source}: {exc}") from None
    aux = tuple(AuxChannel(c.name, c.kind, c.unit, _filled(c)) for c in record.channels if c.wired)
    masked = [s for c in record.channels if c.wired for s in c.masked_spans(record.sample_rate)]
    others = [c.name for c in travels if c.wired and c is not chosen]
    if others:
        warnings.append(f"travel {chosen.name} is fitted; also wired: {', '.join(others)} "
                        "(choose one with [channels] travel)")
    meta = {"warnings": warnings, "travel_channel": chosen.name, "travel_unit": chosen.unit,
            "travel_map": info,
            "analyser": {"profile": record.profile, "rate_source": record.rate_source, "bare": record.bare,
                         "metadata": record.metadata, "results": record.results,
                         "unparsed": [dict(u) for u in record.unparsed]}}
    if masked:
        meta["masked"] = masked
    # the record's quirks stay visible on every operation stored from it (the page's flags)
    flags = (f"analyser header: {len(record.unparsed)} field(s) kept as text",) if record.unparsed else ()
    if masked:
        flags += (over_range_flag(masked),)
    cap = Capture(travel=np.asarray(travel, dtype=float), sample_rate=float(record.sample_rate), vibration=None,
                  source=source, meta=meta, aux=aux, flags=flags)
    cap = check_finite(cap)
    return cap


def _filled(channel) -> np.ndarray:
    return channel.data if channel.mask is None else filled(channel.data, channel.mask)


def over_range_flag(masked: list) -> str:
    """The operation's flag for its over-range samples: ``over-range samples: T1 12``."""
    count: dict = {}
    for s in masked:
        count[s["channel"]] = count.get(s["channel"], 0) + int(s["count"])
    return OVER_RANGE_FLAG + ": " + ", ".join(f"{k} {v}" for k, v in count.items())


def read_comtrade(cfg_path: str | Path, *, travel_channel: str = "travel", vibration_channel: str = "vibration",
                  encoding: str | None = None, temperature_channel: str | None = None) -> Capture:
    """Read a COMTRADE record and map its channels to ours."""
    record = read_record(cfg_path, encoding=encoding)
    return record_to_capture(record, source=str(cfg_path), travel_channel=travel_channel,
                             vibration_channel=vibration_channel, temperature_channel=temperature_channel)


def load_comtrade_bytes(cfg: bytes | str, dat: bytes | None = None, *, source: str = "upload",
                        travel_channel: str = "travel", vibration_channel: str = "vibration",
                        encoding: str | None = None, temperature_channel: str | None = None) -> Capture:
    """Read a COMTRADE pair (or a CFF when ``dat`` is None) held in memory (uploads)."""
    if isinstance(cfg, str):
        cfg = cfg.encode("utf-8")
    name = source.removeprefix("upload:")
    if dat is None:
        record = read_cff_bytes(cfg, name=name, encoding=encoding)
    else:
        stem = name.rsplit(".", 1)[0]
        record = read_record_bytes(cfg, dat, name=name, dat_name=f"{stem}.dat", encoding=encoding)
    return record_to_capture(record, source=source, travel_channel=travel_channel,
                             vibration_channel=vibration_channel, temperature_channel=temperature_channel)


def record_start_time(record: Record) -> datetime | None:
    """Time of the first sample; UTC unless the record gives its offset."""
    s = record.header.start
    if s is None:
        return None
    offset = record.header.utc_offset_minutes
    tz = timezone.utc if offset is None else timezone(timedelta(minutes=offset))
    micro = int((s.fraction or "0")[:6].ljust(6, "0"))
    return datetime(s.year, s.month, s.day, s.hour, s.minute, s.second, micro, tzinfo=tz)


def record_to_capture(record: Record, *, source: str, travel_channel: str = "travel",
                      vibration_channel: str = "vibration", temperature_channel: str | None = None) -> Capture:
    names = [ch.name.strip() for ch in record.header.analog]
    idx_t = _channel_index(names, travel_channel, source)
    idx_v = _find(names, vibration_channel)
    notes = list(record.warnings)
    if not record.uniform:
        notes.append(f"the samples were resampled to a uniform {record.sample_rate:.6g} Hz")
    if record.samples > MAX_SAMPLES:
        raise CaptureError(f"{source}: {record.samples} samples is more than the {MAX_SAMPLES} a capture may hold")
    ch_t = record.header.analog[idx_t]
    travel = record.uniform_channel(idx_t) * _unit_factor(ch_t.unit, TRAVEL_UNITS, "travel", source)
    vibration = vib_limits = None
    if idx_v is not None:
        ch_v = record.header.analog[idx_v]
        vibration = record.uniform_channel(idx_v) * _unit_factor(ch_v.unit, VIBRATION_UNITS, "vibration", source)
        vib_limits = _channel_limits(ch_v, VIBRATION_UNITS)
    cap = Capture(travel=travel, sample_rate=float(record.sample_rate), vibration=vibration,
                  start_time=record_start_time(record), source=source,
                  travel_limits=_channel_limits(ch_t, TRAVEL_UNITS), vibration_limits=vib_limits,
                  meta={"warnings": notes, "encoding": record.encoding, **_kept_meta(record.hdr_text)},
                  aux=_kept_aux(record, names))
    if temperature_channel:
        temp = _temperature(record, names, temperature_channel, source, notes)
        if temp is not None:
            cap.meta["temperature_c"], cap.meta["temperature_source"] = temp, "channel"
    cap = check_finite(cap)
    return cap


def _temperature(record: Record, names, wanted: str, source: str, notes: list) -> float | None:
    """Median of the temperature channel [C], or None with a note saying why (a missing or odd
    temperature never makes the capture unusable: the operation is just not compensated)."""
    i = _find(names, wanted)
    if i is None:
        notes.append(f"no temperature channel named '{wanted}': operation not temperature-compensated")
        return None
    unit = record.header.analog[i].unit.strip().lower()
    if unit not in TEMPERATURE_UNITS:
        notes.append(f"temperature channel '{wanted}' is in '{record.header.analog[i].unit}', expected "
                     f"C or K: operation not temperature-compensated")
        return None
    factor, offset = TEMPERATURE_UNITS[unit]
    values = record.uniform_channel(i) * factor + offset
    values = values[np.isfinite(values)]
    lo, hi = TEMPERATURE_PLAUSIBLE_C
    t = float(np.median(values)) if values.size else float("nan")
    if not lo <= t <= hi:
        notes.append(f"temperature channel '{wanted}' reads {t:.4g} C, outside {lo:g}..{hi:g} C "
                     f"(sensor fault?): operation not temperature-compensated")
        return None
    return round(t, 3)
# What hvcb's own .hdr (service.acquisition.comtrade_writer) keeps of an analyser record that a
# .cfg cannot say: the coil command (the fit's window start) and the analyser's header.
_KEPT = ("command_s", "command_source", "motion_s", "analyser", "travel_map", "travel_channel", "travel_unit",
         "masked")


def _kept_meta(hdr_text: str | None) -> dict:
    if not hdr_text or not hdr_text.lstrip().startswith("{"):
        return {}
    import json

    try:
        meta = json.loads(hdr_text).get("meta")
    except (ValueError, AttributeError):
        return {}
    return {k: meta[k] for k in _KEPT if isinstance(meta, dict) and k in meta}


def _kept_aux(record: Record, names: list) -> tuple:
    """The recorded channels hvcb's own .hdr lists (``aux``: name, kind, unit), read back from
    the .cfg's ``aux <name>`` channels; none for anyone else's COMTRADE."""
    text = record.hdr_text
    if not text or not text.lstrip().startswith("{"):
        return ()
    import json

    try:
        listed = json.loads(text).get("aux") or []
    except (ValueError, AttributeError):
        return ()
    out = []
    for entry in listed if isinstance(listed, list) else []:
        if not isinstance(entry, dict) or not {"name", "kind", "unit"} <= set(entry):
            continue
        i = _find(names, AUX_PREFIX + str(entry["name"]))
        if i is not None:
            out.append(AuxChannel(str(entry["name"]), str(entry["kind"]), str(entry["unit"]),
                                  record.uniform_channel(i)))
    return tuple(out)


def _channel_limits(ch, table) -> tuple | None:
    f = table.get(ch.unit.strip().lower(), 1.0)
    lo, hi = sorted(((ch.a * ch.cmin + ch.b) * f, (ch.a * ch.cmax + ch.b) * f))
    return (float(lo), float(hi)) if hi > lo and np.isfinite([lo, hi]).all() else None


def _find(names, wanted: str) -> int | None:
    for i, name in enumerate(names):
        if name.lower() == wanted.strip().lower():
            return i
    return None


def _channel_index(names, wanted: str, source: str) -> int:
    i = _find(names, wanted)
    if i is None:
        shown = ", ".join(names[:40]) + (f" and {len(names) - 40} more" if len(names) > 40 else "")
        raise CaptureError(f"{source}: no channel named '{wanted}' (channels: {shown or 'none'}); "
                           f"set the channel name in the breaker file's [channels]")
    return i


def _unit_factor(unit: str, table: dict, quantity: str, source: str) -> float:
    key = unit.strip().lower()
    if key == "" and quantity == "travel":
        raise CaptureError(f"{source}: the {quantity} channel has no unit; expected one of {', '.join(table)}")
    if key == "":
        return 1.0
    if key not in table:
        raise CaptureError(f"{source}: the {quantity} channel is in '{unit}', expected one of {', '.join(table)}")
    return table[key]


def read_csv_text(path: str | Path, *, encoding: str | None = None) -> tuple[str, str]:
    """``(text, encoding)`` of a CSV capture."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise CaptureError(f"cannot read {path} ({exc.strerror or 'input/output error'})") from None
    return decode_text(data, name=str(path), encoding=encoding)


def read_csv(path: str | Path, *, encoding: str | None = None) -> Capture:
    """Read a CSV with a header ``t_s,travel_rad[,vibration_g]`` and uniform sampling."""
    text, _ = read_csv_text(path, encoding=encoding)
    return parse_csv(text, source=str(path))


def parse_csv(text: str, *, source: str = "csv") -> Capture:
    text = text.replace("\x1a", "")
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise CaptureError(f"{source}: empty file")
    header = [h.strip().lower() for h in lines[0].rstrip(", \t").split(",")]
    if header[:2] != ["t_s", "travel_rad"]:
        if len(header) >= 2 and header[0] == "t_s" and header[1].startswith("travel_"):
            raise CaptureError(f"{source}: travel column is '{header[1]}', expected travel_rad (radians)")
        raise CaptureError(f"{source}: expected a header 't_s,travel_rad[,vibration_g]', got '{lines[0][:80]}'")
    if len(header) > 2 and header[2] not in ("vibration_g",):
        raise CaptureError(f"{source}: third column is '{header[2]}', expected vibration_g")
    body = "\n".join(ln.strip().rstrip(",") for ln in lines[1:])
    try:
        data = np.loadtxt(io.StringIO(body), delimiter=",", ndmin=2)
    except ValueError:
        raise CaptureError(f"{source}: {first_bad_row(lines, len(header))}") from None
    if data.shape[0] < 2:
        raise CaptureError(f"{source}: fewer than 2 samples")
    if data.shape[1] != len(header):
        raise CaptureError(f"{source}: the rows hold {data.shape[1]} values, the header names {len(header)}")
    t = data[:, 0]
    dt = np.diff(t)
    if not np.all(np.isfinite(t)) or np.any(dt <= 0):
        raise CaptureError(f"{source}: the time column must be finite and strictly increasing")
    period = float(np.median(dt))
    if np.max(np.abs(dt - period)) > 0.01 * period + 1e-9:
        raise CaptureError(f"{source}: the samples are not uniformly spaced in time")
    cap = Capture(travel=data[:, 1].astype(float), sample_rate=1.0 / period,
                  vibration=data[:, 2].astype(float) if data.shape[1] > 2 else None, source=source)
    cap = check_finite(cap)
    return cap


def first_bad_row(lines: list, width: int) -> str:
    for i, line in enumerate(lines[1:], 2):
        parts = [p.strip() for p in line.strip().rstrip(",").split(",")]
        if len(parts) != width:
            return f"row {i} has {len(parts)} values, the header names {width}"
        for p in parts:
            try:
                float(p)
            except ValueError:
                return f"row {i}: '{p[:20]}' is not a number"
    return "not numeric CSV"


def check_finite(cap: Capture) -> Capture:
    """Refuse a travel with NaN or infinite samples; a vibration channel with them is dropped
    instead (the fit does not need it), its reason kept in ``meta["vibration_unread"]`` and the
    warnings: a bad accelerometer never fails the upload (service/vibration reports the reason)."""
    if not np.all(np.isfinite(cap.travel)):
        n = int(np.sum(~np.isfinite(cap.travel)))
        raise CaptureError(f"{cap.source}: the travel channel has {n} NaN or infinite samples")
    if cap.vibration is not None and not np.all(np.isfinite(cap.vibration)):
        bad = ~np.isfinite(cap.vibration)
        reason = (f"the vibration channel has {int(bad.sum())} NaN or infinite samples (the first at "
                  f"{int(np.argmax(bad)) / cap.sample_rate * 1e3:.1f} ms): a broken sensor or cable; it is left out")
        meta = {**cap.meta, "vibration_unread": reason,
                "warnings": list(cap.meta.get("warnings") or []) + [reason]}
        return replace(cap, vibration=None, vibration_limits=None, meta=meta)
    return cap
