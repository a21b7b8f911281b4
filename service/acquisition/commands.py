"""``hvcb detect`` (operations in a recording) and ``hvcb capture`` (driver → COMTRADE files)."""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
from pathlib import Path

DEFAULT_BREAKER = "config/breakers/reference-252kV.toml"


def register(subparsers) -> None:
    d = subparsers.add_parser(
        "detect", help="find the operations in a recording (COMTRADE .cfg or CSV t_s,travel_rad,vibration_g)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    d.add_argument("stream", help="recording: COMTRADE .cfg/.cff or CSV with t_s,travel_rad,vibration_g")
    d.add_argument("--breaker", default=DEFAULT_BREAKER, help="breaker file (stroke, trigger levels, channels)")
    d.add_argument("--json", action="store_true", help="print a JSON list, one object per operation")
    d.add_argument("--rate", type=_rate, default=None,
                   help="sampling rate of a bare analyser export that states none [Hz; 10k = 10 kS/s]")
    _trigger_options(d)
    d.set_defaults(func=run_detect)

    c = subparsers.add_parser(
        "capture", help="acquire from a DAQ driver and write each operation as COMTRADE",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    c.add_argument("--driver", choices=("serial", "modbus", "replay"), required=True)
    c.add_argument("--out", required=True, help="directory for the COMTRADE files")
    c.add_argument("--breaker", default=DEFAULT_BREAKER, help="breaker file (scaling, trigger levels)")
    c.add_argument("--format", default="BINARY", choices=("BINARY", "ASCII", "BINARY32", "FLOAT32"))
    c.add_argument("--max-captures", type=int, default=None, help="stop after this many captures")
    c.add_argument("--json", action="store_true", help="print one JSON line per capture written")
    g = c.add_argument_group("replay driver")
    g.add_argument("--file", action="append", default=[], metavar="PATH",
                   help="recording to replay (COMTRADE .cfg or CSV); repeat for several")
    g.add_argument("--speed", type=float, default=0.0,
                   help="replay pace: 1 = real time, N = N x, 0 = as fast as possible")
    g.add_argument("--block-samples", type=int, default=4096, help="samples per replayed block")
    g = c.add_argument_group("serial driver")
    g.add_argument("--url", default="", help="device path, pty or socket://host:port (serial; modbus rtu)")
    g.add_argument("--baudrate", type=int, default=None, help="serial line rate [bit/s]")
    g = c.add_argument_group("modbus driver")
    g.add_argument("--transport", choices=("tcp", "rtu"), default="tcp")
    g.add_argument("--host", default="127.0.0.1")
    g.add_argument("--port", type=int, default=502)
    g.add_argument("--device-id", type=int, default=1)
    _trigger_options(c)
    c.set_defaults(func=run_capture)


def _rate(text):
    from service.arguments import rate_hz

    return rate_hz(text)


def _trigger_options(p) -> None:
    p.add_argument("--shock-threshold-g", type=float, default=None,
                   help="latch-shock level [g] (default: the breaker file's [acquisition])")
    p.add_argument("--motion-fraction", type=float, default=None,
                   help="travel fraction of the stroke confirming an operation (default: breaker file)")


def _settings(args):
    from service.breaker_file import load_breaker

    from .trigger import TriggerSettings

    breaker = load_breaker(args.breaker)
    overrides = {}
    if args.shock_threshold_g is not None:
        overrides["shock_threshold_g"] = args.shock_threshold_g
    if args.motion_fraction is not None:
        overrides["motion_fraction"] = args.motion_fraction
    return breaker, TriggerSettings.from_breaker(breaker, **overrides)


def run_detect(args) -> int:
    from .capture_file import breaker_reading, read_capture
    from .recording import detect_capture

    breaker, settings = _settings(args)
    recording = read_capture(args.stream, **breaker_reading(breaker), rate=args.rate)
    from service.progress import progress

    with progress(recording.travel.size, desc=f"detect {Path(args.stream).name}", unit="sample",
                  unit_scale=True) as bar:
        found = detect_capture(recording, settings, on_progress=bar.update)
    rows = [op.to_dict(origin_index=recording.first_sample_index) for op in found]
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    if not rows:
        print(f"{args.stream}: no operation found")
        return 0
    print(f"{'operation':9} {'t_start_s':>10} {'t_end_s':>10}  flags")
    for r in rows:
        print(f"{r['operation']:9} {r['t_start_s']:10.6f} {r['t_end_s']:10.6f}  {','.join(r['flags']) or '-'}")
    return 0


def make_driver(args, breaker):
    """The driver ``args`` ask for; driver modules are imported only when used."""
    if args.driver == "replay":
        if not args.file:
            raise ValueError("the replay driver needs --file PATH (a COMTRADE .cfg or a CSV stream)")
        for f in args.file:
            if not Path(f).is_file():
                raise ValueError(f"recording not found: {f}")
        from drivers.replay import ReplayDriver

        return ReplayDriver([Path(f) for f in args.file], block_samples=args.block_samples,
                            speed=args.speed if args.speed > 0 else None)
    from drivers.scaling import ChannelScaling

    scaling = ChannelScaling.from_breaker(breaker)
    if args.driver == "serial":
        if not args.url:
            raise ValueError("the serial driver needs --url (device path, pty, or socket://host:port)")
        from drivers.serial_stream import SerialSettings, SerialStreamDriver

        extra = {"baudrate": args.baudrate} if args.baudrate else {}
        return SerialStreamDriver(SerialSettings(url=args.url, **extra), scaling)
    from drivers.modbus import ModbusCaptureDriver, ModbusSettings

    extra = {"baudrate": args.baudrate} if args.baudrate else {}
    settings = ModbusSettings(transport=args.transport, host=args.host, port=args.port, url=args.url,
                              device_id=args.device_id, **extra)
    return ModbusCaptureDriver(settings, scaling)


def run_capture(args) -> int:
    from .pipeline import capture_stream

    breaker, settings = _settings(args)
    driver = make_driver(args, breaker)

    def report(path, det):
        if args.json:
            print(json.dumps({"file": str(path), **det.to_dict()}), flush=True)
        else:
            print(f"{path}: {det.operation} at {det.window_start_s:.6f} s "
                  f"{','.join(det.flags) or ''}".rstrip(), flush=True)

    stats = asyncio.run(capture_stream(driver, settings, args.out, on_capture=report, fmt=args.format,
                                       station=breaker.name, max_captures=args.max_captures))
    print(f"{stats.captures} captures ({stats.incomplete} incomplete) from {stats.samples} samples, "
          f"{stats.gaps} gaps", file=sys.stderr)
    return 0
