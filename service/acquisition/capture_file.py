"""Reading captures from COMTRADE (C37.111-1999/2013: ASCII, BINARY, BINARY32, FLOAT32) and CSV.

Outside names and units become ours here: the travel channel in rad, the vibration in g.
"""

from __future__ import annotations

import io
import warnings
from datetime import timezone
from pathlib import Path

import numpy as np

from drivers.capture import Capture, CaptureError

# Unit spellings accepted per quantity, with the factor to our unit.
TRAVEL_UNITS = {"rad": 1.0, "radian": 1.0, "radians": 1.0, "deg": np.pi / 180, "degree": np.pi / 180,
                "degrees": np.pi / 180, "°": np.pi / 180, "mrad": 1e-3}
VIBRATION_UNITS = {"g": 1.0, "gn": 1.0, "m/s2": 1 / 9.80665, "m/s^2": 1 / 9.80665, "m/s²": 1 / 9.80665}

MAX_SAMPLES = 50_000_000


def read_capture(path: str | Path, *, travel_channel: str = "travel",
                 vibration_channel: str = "vibration") -> Capture:
    """Read a COMTRADE ``.cfg`` (with its ``.dat``), a ``.cff``, or a CSV ``t_s,travel_rad[,vibration_g]``.

    Raises
    ------
    CaptureError
        Missing or malformed files, unknown channels, wrong units or NaN samples.
    """
    path = Path(path)
    if not path.exists():
        raise CaptureError(f"capture file not found: {path}")
    suffix = path.suffix.lower()
    if suffix in (".cfg", ".cff"):
        return read_comtrade(path, travel_channel=travel_channel, vibration_channel=vibration_channel)
    if suffix in (".csv", ".txt"):
        return read_csv(path)
    if suffix == ".dat":
        return read_comtrade(path.with_suffix(".cfg"), travel_channel=travel_channel,
                             vibration_channel=vibration_channel)
    raise CaptureError(f"unknown capture format '{path.suffix}': give a COMTRADE .cfg or a .csv")


def read_comtrade(cfg_path: str | Path, *, travel_channel: str = "travel",
                  vibration_channel: str = "vibration") -> Capture:
    """Read a COMTRADE record with the ``comtrade`` package and map its channels to ours."""
    import comtrade

    cfg_path = Path(cfg_path)
    if not cfg_path.is_file():
        raise CaptureError(f"COMTRADE configuration not found: {cfg_path}")
    record = comtrade.Comtrade()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if cfg_path.suffix.lower() == ".cff":
                record.load(str(cfg_path))
            else:
                dat = _find_dat(cfg_path)
                record.load(str(cfg_path), str(dat))
    except CaptureError:
        raise
    except Exception as exc:  # the reader raises many types on malformed input
        raise CaptureError(f"malformed COMTRADE {cfg_path.name}: {type(exc).__name__}: {exc}") from None
    return comtrade_to_capture(record, source=str(cfg_path), travel_channel=travel_channel,
                               vibration_channel=vibration_channel)


def load_comtrade_bytes(cfg_text: str, dat_bytes: bytes, *, source: str = "upload",
                        travel_channel: str = "travel", vibration_channel: str = "vibration") -> Capture:
    """Read a COMTRADE pair held in memory (uploads)."""
    import comtrade

    record = comtrade.Comtrade()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            record.read(cfg_text, dat_bytes if _is_binary(cfg_text) else dat_bytes.decode("ascii"))
    except Exception as exc:
        raise CaptureError(f"malformed COMTRADE upload: {type(exc).__name__}: {exc}") from None
    return comtrade_to_capture(record, source=source, travel_channel=travel_channel,
                               vibration_channel=vibration_channel)


def _is_binary(cfg_text: str) -> bool:
    return any(line.strip().upper() in ("BINARY", "BINARY32", "FLOAT32") for line in cfg_text.splitlines())


def _find_dat(cfg_path: Path) -> Path:
    for suffix in (".dat", ".DAT"):
        candidate = cfg_path.with_suffix(suffix)
        if candidate.is_file():
            return candidate
    raise CaptureError(f"COMTRADE data file missing next to {cfg_path.name} (expected {cfg_path.stem}.dat)")


def comtrade_to_capture(record, *, source: str, travel_channel: str = "travel",
                        vibration_channel: str = "vibration") -> Capture:
    names = [str(n).strip() for n in record.analog_channel_ids]
    units = [str(u).strip() for u in getattr(record.cfg, "analog_channels", [])
             and [ch.uu for ch in record.cfg.analog_channels]] or [""] * len(names)
    idx_t = _channel_index(names, travel_channel, source)
    try:
        idx_v = _channel_index(names, vibration_channel, source)
    except CaptureError:
        idx_v = None
    rates = record.cfg.sample_rates
    if not rates or rates[0][0] <= 0:
        raise CaptureError(f"{source}: the COMTRADE file gives no sampling rate; timestamps alone are too coarse")
    if len(rates) > 1:
        raise CaptureError(f"{source}: {len(rates)} sampling rates in one record are not supported")
    fs = float(rates[0][0])
    travel = np.asarray(record.analog[idx_t], dtype=float) * _unit_factor(units[idx_t], TRAVEL_UNITS, "travel", source)
    vibration = None
    vib_limits = None
    if idx_v is not None:
        vibration = np.asarray(record.analog[idx_v], dtype=float) * _unit_factor(
            units[idx_v], VIBRATION_UNITS, "vibration", source)
        vib_limits = _channel_limits(record, idx_v, VIBRATION_UNITS, units[idx_v])
    if travel.size == 0:
        raise CaptureError(f"{source}: the record holds no samples")
    start = getattr(record, "start_timestamp", None)
    if start is not None and start.tzinfo is None:
        start = start.replace(tzinfo=timezone.utc)
    cap = Capture(travel=travel, sample_rate=fs, vibration=vibration, start_time=start, source=source,
                  travel_limits=_channel_limits(record, idx_t, TRAVEL_UNITS, units[idx_t]),
                  vibration_limits=vib_limits)
    check_finite(cap)
    return cap


def _channel_limits(record, idx, table, unit):
    try:
        ch = record.cfg.analog_channels[idx]
        lo = ch.a * ch.cmin + ch.b
        hi = ch.a * ch.cmax + ch.b
        f = table.get(unit.lower(), 1.0)
        lo, hi = sorted((lo * f, hi * f))
        return (float(lo), float(hi)) if hi > lo else None
    except Exception:
        return None


def _channel_index(names, wanted: str, source: str) -> int:
    for i, name in enumerate(names):
        if name.lower() == wanted.lower():
            return i
    raise CaptureError(f"{source}: no channel named '{wanted}' (channels: {', '.join(names) or 'none'}); "
                       f"set the channel name in the breaker file's [channels]")


def _unit_factor(unit: str, table: dict, quantity: str, source: str) -> float:
    key = unit.strip().lower()
    if key == "" and quantity == "travel":
        raise CaptureError(f"{source}: the {quantity} channel has no unit; expected one of {', '.join(table)}")
    if key == "":
        return 1.0
    if key not in table:
        raise CaptureError(f"{source}: the {quantity} channel is in '{unit}', expected one of {', '.join(table)}")
    return table[key]


def read_csv(path: str | Path) -> Capture:
    """Read a CSV with a header ``t_s,travel_rad[,vibration_g]`` and uniform sampling."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise CaptureError(f"cannot read {path}: {exc}") from None
    return parse_csv(text, source=str(path))


def parse_csv(text: str, *, source: str = "csv") -> Capture:
    lines = text.splitlines()
    if not lines:
        raise CaptureError(f"{source}: empty file")
    header = [h.strip().lower() for h in lines[0].split(",")]
    if header[:2] != ["t_s", "travel_rad"]:
        if len(header) >= 2 and header[0] == "t_s" and header[1].startswith("travel_"):
            raise CaptureError(f"{source}: travel column is '{header[1]}', expected travel_rad (radians)")
        raise CaptureError(f"{source}: expected a header 't_s,travel_rad[,vibration_g]', got '{lines[0][:80]}'")
    if len(header) > 2 and header[2] not in ("vibration_g",):
        raise CaptureError(f"{source}: third column is '{header[2]}', expected vibration_g")
    try:
        data = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1, ndmin=2)
    except ValueError as exc:
        raise CaptureError(f"{source}: not numeric CSV: {exc}") from None
    if data.shape[0] < 2:
        raise CaptureError(f"{source}: fewer than 2 samples")
    t = data[:, 0]
    dt = np.diff(t)
    if not np.all(np.isfinite(t)) or np.any(dt <= 0):
        raise CaptureError(f"{source}: the time column must be finite and strictly increasing")
    period = float(np.median(dt))
    if np.max(np.abs(dt - period)) > 0.01 * period + 1e-9:
        raise CaptureError(f"{source}: the samples are not uniformly spaced in time")
    cap = Capture(travel=data[:, 1].astype(float), sample_rate=1.0 / period,
                  vibration=data[:, 2].astype(float) if data.shape[1] > 2 else None, source=source)
    check_finite(cap)
    return cap


def check_finite(cap: Capture) -> None:
    if not np.all(np.isfinite(cap.travel)):
        n = int(np.sum(~np.isfinite(cap.travel)))
        raise CaptureError(f"{cap.source}: the travel channel has {n} NaN or infinite samples")
    if cap.vibration is not None and not np.all(np.isfinite(cap.vibration)):
        raise CaptureError(f"{cap.source}: the vibration channel has NaN or infinite samples")
