"""``hvcb inspect``: what is in a capture file (the ffprobe of a capture).

Reads a COMTRADE record (``.cfg``+``.dat``, ``.cff``) or a CSV with the same reader that serves
``fit``, ``detect`` and uploads, and reports its header, channels (min/median/max in engineering
units) and everything the reader had to repair or guess. No breaker file is needed; with one
the report names the channels it would use for travel and vibration.
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np

from drivers.capture import CaptureError

MAX_LISTED = 40  # channel names printed in the table before "... and N more"


def register(subparsers) -> None:
    p = subparsers.add_parser("inspect", help="report what a capture file holds (COMTRADE .cfg/.cff or CSV)")
    p.add_argument("capture", help="COMTRADE .cfg (with its .dat), .dat, .cff, or .csv")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--breaker", default=None, help="breaker file: adds the travel/vibration channel mapping")
    p.add_argument("--rate", default=None, type=_rate,
                   help="sampling rate of a bare analyser export that states none [Hz; 10k = 10 kS/s]")
    p.add_argument("--encoding", default=None,
                   help="text encoding of the names (default: UTF-8, else detected: cp1251, GBK, ISO-8859-1)")
    p.set_defaults(func=run_inspect)


def _rate(text):
    from service.arguments import rate_hz

    return rate_hz(text)


def run_inspect(args) -> int:
    channels = None
    if args.breaker:
        from service.breaker_file import load_breaker

        channels = load_breaker(args.breaker).channels
    report = inspect_capture(args.capture, channels=channels, encoding=args.encoding, rate=args.rate)
    if args.json:
        print(json.dumps(report, ensure_ascii=False, allow_nan=False))
    else:
        print(format_report(report))
    return 0


def inspect_capture(path: str | Path, *, channels: dict | None = None, encoding: str | None = None,
                    rate: float | None = None) -> dict:
    """The report of one capture file as a JSON-able dict.

    ``channels`` is a breaker file's ``[channels]`` (``{"travel": name, "vibration": name}``);
    without it the default names ``travel`` and ``vibration`` are looked up.
    """
    path = Path(path)
    if not path.exists():
        raise CaptureError(f"capture file not found: {path}")
    if path.is_dir():
        raise CaptureError(f"{path} is a folder; give the capture's .cfg, .cff or .csv file")
    suffix = path.suffix.lower()
    analyser = None
    if suffix not in (".cfg", ".cff", ".dat"):
        from drivers.analyser import looks_like_analyser
        from drivers.capture_file import sniff_text

        text, enc = sniff_text(path, encoding)
        if text is not None and looks_like_analyser(text):
            analyser = (text, enc)
    if analyser is not None:
        report = _inspect_analyser(path, *analyser, rate)
    elif suffix in (".csv", ".txt"):
        report = _inspect_csv(path, encoding)
    elif suffix in (".cfg", ".cff", ".dat"):
        report = _inspect_comtrade(path, encoding)
    else:
        raise CaptureError(f"{path}: unknown capture format '{path.suffix}'; give a COMTRADE .cfg/.cff, "
                           "an analyser export or a .csv")
    wanted = {"travel": "travel", "vibration": "vibration", **(channels or {})}
    names = {a["name"].strip().lower(): a["name"] for a in reversed(report["analog"])}
    report["mapping"] = {k: names.get(str(wanted[k]).strip().lower()) for k in ("travel", "vibration")}
    if report.get("container") == "analyser CSV" and str(wanted["travel"]).strip().lower() == "travel":
        wired = [a["name"] for a in report["analog"] if a.get("kind") == "travel" and a.get("wired")]
        clean = [n for n in wired if not any(m["channel"] == n for m in report["masked"])]
        # the first wired contact travel without over-range samples, as the capture reader picks it
        report["mapping"]["travel"] = (clean or wired or [None])[0]
    report["mapping_source"] = "breaker file" if channels else "default channel names"
    return report


def _stats(x: np.ndarray) -> dict:
    x = np.asarray(x, float)
    ok = x[np.isfinite(x)]
    if ok.size == 0:
        return {"min": None, "median": None, "max": None}
    return {"min": float(ok.min()), "median": float(np.median(ok)), "max": float(ok.max())}


def _inspect_comtrade(path: Path, encoding: str | None) -> dict:
    from drivers.comtrade import read_record

    rec = read_record(path, encoding=encoding)
    h = rec.header
    offset = h.utc_offset_minutes
    revision = h.revision or "1991"
    return {
        "file": str(path),
        "container": rec.container,
        "revision": revision,
        "read_as_revision": h.standard_revision,
        "file_type": h.file_type,
        "encoding": rec.encoding,
        "hdr_encoding": rec.hdr_encoding,
        "inf_encoding": rec.inf_encoding,
        "station": h.station,
        "device": h.device,
        "line_frequency_hz": h.line_frequency,
        "sample_rate_hz": float(rec.sample_rate),
        "rate_source": rec.rate_source,
        "rate_sections": [{"rate_hz": float(r), "last_sample": int(n)} for r, n in h.rates] if h.nrates else [],
        "samples": rec.samples,
        "declared_samples": h.declared_samples,
        "duration_s": rec.samples / float(rec.sample_rate),
        "start": h.start.iso(offset) if h.start else None,
        "trigger": h.trigger.iso(offset) if h.trigger else None,
        "analog": [{"name": ch.name, "unit": ch.unit, **_stats(x)} for ch, x in zip(h.analog, rec.analog)],
        "digital": [{"name": ch.name} for ch in h.digital],
        "warnings": list(rec.warnings),
        "masked": _stored_masked(path),
    }


def _stored_masked(path: Path) -> list:
    """hvcb's own COMTRADE keeps a record's over-range spans in its .hdr."""
    from .comtrade_writer import stored_masked_spans

    return stored_masked_spans(path) if path.suffix.lower() == ".cfg" else []


def _inspect_analyser(path: Path, text: str, enc: str, rate: float | None) -> dict:
    """A breaker-analyser export: every table channel in its own unit (wired or not), the
    header's metadata and the analyser's own results."""
    from drivers.analyser import parse_analyser

    rec = parse_analyser(text, source=str(path), rate=rate, require_rate=False)
    fs = rec.sample_rate
    md = rec.metadata
    return {
        "file": str(path), "container": "analyser CSV", "revision": None, "read_as_revision": None,
        "file_type": rec.profile, "encoding": enc, "hdr_encoding": None, "inf_encoding": None,
        "station": md.get("station"), "device": md.get("breaker_type"), "line_frequency_hz": None,
        "sample_rate_hz": fs, "rate_source": rec.rate_source, "rate_sections": [], "samples": rec.samples,
        "declared_samples": None, "duration_s": rec.samples / fs if fs else None,
        "start": None, "trigger": None,
        "analog": [{"name": c.name, "unit": c.unit, "kind": c.kind, "column": c.column, "wired": c.wired,
                    **_stats(c.data)} for c in rec.channels],
        "digital": [], "warnings": list(rec.warnings), "bare": rec.bare,
        "metadata": md, "results": rec.results, "unparsed": [dict(u) for u in rec.unparsed],
        "masked": [m for c in rec.channels for m in c.masked_spans(fs)],
        "over_range_throughout": [c.name for c in rec.channels if c.over_range_throughout],
        "coils": _coils(rec),
    }


def _coils(rec) -> list:
    """Each energised coil's peak, armature dip and current end (service.vibration.coils), beside
    the analyser's own peak where the header states one."""
    from service.vibration import coil_results

    stated = (rec.results or {}).get("coil_current_peak_a") or {}
    out = []
    for c in rec.channels:
        if c.kind == "coil_current" and c.wired:
            peak = stated.get(c.name)
            out += coil_results(c.name, c.data, rec.sample_rate, analyser_peak_a=peak)  # checked there
    return out


def _inspect_csv(path: Path, encoding: str | None) -> dict:
    from drivers.capture_file import read_csv_text

    text, enc = read_csv_text(path, encoding=encoding)
    warnings = []
    if "\x1a" in text:
        text = text.replace("\x1a", "")
        warnings.append("Ctrl-Z padding was ignored")
    lines = [ln.strip().rstrip(",") for ln in text.splitlines()]
    blank = sum(1 for ln in lines if not ln)
    lines = [ln for ln in lines if ln]
    if blank:
        warnings.append(f"{blank} blank line(s) were skipped")
    if not lines:
        raise CaptureError(f"{path}: empty file")
    header = [h.strip() for h in lines[0].split(",")]
    try:
        data = np.loadtxt(io.StringIO("\n".join(lines[1:])), delimiter=",", ndmin=2)
    except ValueError:
        from drivers.capture_file import first_bad_row

        raise CaptureError(f"{path}: {first_bad_row(lines, len(header))}") from None
    if data.shape[0] == 0:
        raise CaptureError(f"{path}: the file holds a header but no samples")
    if data.shape[1] != len(header):
        raise CaptureError(f"{path}: the rows hold {data.shape[1]} values, the header names {len(header)}")
    rate = None
    t = data[:, 0]
    if header[0].lower() in ("t_s", "t", "time", "time_s") and data.shape[0] >= 2:
        dt = np.diff(t)
        if np.all(np.isfinite(t)) and np.all(dt > 0):
            period = (t[-1] - t[0]) / (t.size - 1)
            rate = 1.0 / period
            if np.max(np.abs(dt - period)) > 0.01 * period:
                warnings.append("the time column is not equally spaced")
        else:
            warnings.append("the time column does not increase")
    else:
        warnings.append(f"the first column '{header[0]}' is not a time column (t_s); no sampling rate")

    def split(name):
        base, _, unit = name.rpartition("_")
        return (base, unit) if base else (name, "")

    analog = [{"name": split(n)[0], "unit": split(n)[1], **_stats(data[:, k + 1])}
              for k, n in enumerate(header[1:])]
    return {
        "file": str(path), "container": "CSV", "revision": None, "read_as_revision": None, "file_type": "CSV",
        "encoding": enc, "hdr_encoding": None, "inf_encoding": None, "station": None, "device": None,
        "line_frequency_hz": None, "sample_rate_hz": rate, "rate_source": "time column" if rate else None,
        "rate_sections": [], "samples": int(data.shape[0]), "declared_samples": None,
        "duration_s": data.shape[0] / rate if rate else None, "start": None, "trigger": None,
        "analog": analog, "digital": [], "warnings": warnings,
    }


def _num(x) -> str:
    if isinstance(x, str):  # a header value kept as written (listed under "unparsed")
        return x
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.6g}"


def format_report(r: dict) -> str:
    """The report as a short table for the terminal."""
    rev = r["revision"]
    fmt = r["file_type"] if rev is None else (
        f"COMTRADE {rev}" + (f" (read as {r['read_as_revision']})" if r["read_as_revision"] != rev else "")
        + f", {r['file_type']}, {r['container']}")
    enc = r["encoding"] + "".join(f", {k} {r[k + '_encoding']}" for k in ("hdr", "inf") if r.get(k + "_encoding"))
    rate = "unknown rate" if r["sample_rate_hz"] is None else f"{_num(r['sample_rate_hz'])} Hz"
    if r.get("rate_source") == "time stamps":
        rate += " (from the time stamps)"
    if len(r.get("rate_sections") or []) > 1:
        rate += f" (mean of {len(r['rate_sections'])} rate sections)"
    out = [f"file      {r['file']}", f"format    {fmt}; text {enc}"]
    if r.get("station") or r.get("device"):
        out.append(f"recorder  {r['station']} / {r['device']}")
    out.append(f"samples   {r['samples']} at {rate}"
               + (f", {_num(r['duration_s'])} s" if r["duration_s"] is not None else ""))
    if r["start"] or r["trigger"]:
        out.append(f"start     {r['start'] or '-'}   trigger {r['trigger'] or '-'}")
    rows = [(a["name"] + ("" if a.get("wired", True) else " (not wired)"), a["unit"], _num(a["min"]),
             _num(a["median"]), _num(a["max"])) for a in r["analog"]]
    head = ("name", "unit", "min", "median", "max")
    widths = [max(len(str(x[i])) for x in rows + [head]) for i in range(5)]
    out.append(f"analog    {len(rows)}")
    for row in [head] + rows[:MAX_LISTED]:
        out.append("  " + "  ".join(str(v).ljust(w) if i < 2 else str(v).rjust(w)
                                    for i, (v, w) in enumerate(zip(row, widths))).rstrip())
    if len(rows) > MAX_LISTED:
        out.append(f"  ... and {len(rows) - MAX_LISTED} more")
    digital = [d["name"] for d in r["digital"]]
    if digital:
        more = f" ... and {len(digital) - MAX_LISTED} more" if len(digital) > MAX_LISTED else ""
        out.append(f"digital   {len(digital)}: " + ", ".join(digital[:MAX_LISTED]) + more)
    m = r["mapping"]
    out.append(f"mapping   travel: {m['travel'] or 'none'}, vibration: {m['vibration'] or 'none'} "
               f"({r['mapping_source']})")
    if r.get("results"):
        out.append("analyser results")
        for name, v in r["results"].items():
            if isinstance(v, dict):
                shown = ", ".join(f"{k} {_num(x)}" for k, x in v.items() if x not in (None, 0, 0.0))
                out.append(f"  {name}: {shown or 'all zero'}")
            else:
                out.append(f"  {name}: {_num(v) if isinstance(v, float) else v}")
    if r.get("unparsed"):
        out.append(f"unparsed  {len(r['unparsed'])} header field(s) kept as written")
        out += [f"  line {u['line']}: {u['key']} = {u['text']!r} ({u['why']})" for u in r["unparsed"]]
    if r.get("masked"):
        from drivers.masked import describe

        out.append(f"masked    {sum(m['count'] for m in r['masked'])} over-range sample(s) in "
                   f"{len(r['masked'])} span(s) (marked ∞ or NaN: missing, not measured)")
        out += [f"  {describe(m)}" for m in r["masked"][:MAX_LISTED]]
        if len(r["masked"]) > MAX_LISTED:
            out.append(f"  ... and {len(r['masked']) - MAX_LISTED} more")
    if r.get("over_range_throughout"):
        out.append("refused   over-range throughout (no reading): " + ", ".join(r["over_range_throughout"]))
    if r["warnings"]:
        out.append("warnings")
        out += [f"  - {w}" for w in r["warnings"]]
    return "\n".join(out)
