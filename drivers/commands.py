"""``hvcb emulate serial|modbus``: run a DAQ emulator by hand and point a driver at it."""

from __future__ import annotations

import argparse
import asyncio
import json
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

DEFAULT_BREAKER = "config/breakers/reference-252kV.toml"


def register(subparsers) -> None:
    p = subparsers.add_parser("emulate", help="run a DAQ emulator (serial stream or Modbus capture buffer)")
    sub = p.add_subparsers(dest="emulator", required=True)

    s = sub.add_parser("serial", help="stream frames to a pty or a TCP port (pyserial socket://)",
                       formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    _common(s)
    s.add_argument("--pty", action="store_true", help="write to a new pty instead of a TCP port")
    s.add_argument("--port", type=int, default=0, help="TCP port (0: pick a free one)")
    s.add_argument("--speed", type=float, default=1.0, help="1 = real time 128 kS/s, N = N x, 0 = unthrottled")
    s.add_argument("--duration", type=float, default=60.0, help="stream length [s of samples]")
    s.add_argument("--script", choices=("alternating", "acceptance"), default="alternating",
                   help="alternating: open/close every second; acceptance: the issue's 60 s stream "
                        "with 12 operations, lone shocks, a noise burst and a clipped shock")
    s.add_argument("--return-shape", choices=("model", "critical", "oscillating"), default="model",
                   help="how openings return from overtravel to rest: the model's own slow return, "
                        "critically damped (at rest within 5 ms), or oscillating (the rebound swings "
                        "past rest)")
    s.add_argument("--frame-samples", type=int, default=256, help="samples per frame")
    for fault in ("corrupt", "drop", "garbage", "disconnect"):
        s.add_argument(f"--{fault}-every", type=int, default=0, metavar="N",
                       help=f"{fault} every N-th frame (0: never)")
    s.set_defaults(func=run_serial)

    m = sub.add_parser("modbus", help="serve captures in the Modbus register map (TCP or RTU over TCP)",
                       formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    _common(m)
    m.add_argument("--transport", choices=("tcp", "rtu"), default="tcp",
                   help="rtu: RTU framing on a TCP port (client URL socket://host:port)")
    m.add_argument("--port", type=int, default=5020, help="TCP port (0: pick a free one)")
    m.add_argument("--device-id", type=int, default=1)
    m.add_argument("--captures", type=int, default=4, help="operations to queue (open, close, ...)")
    m.add_argument("--delay-at", type=int, default=0, metavar="READ",
                   help="answer this payload read late (0: never)")
    m.add_argument("--delay-s", type=float, default=2.0, help="lateness of that reply [s]")
    m.add_argument("--exception-at", type=int, default=0, metavar="READ",
                   help="answer this payload read with an exception response (0: never)")
    m.add_argument("--linger", type=float, default=0.0,
                   help="keep serving this long after the last capture is acknowledged [s] (0: until Ctrl-C)")
    m.set_defaults(func=run_modbus)


def _common(p) -> None:
    p.add_argument("--breaker", default=DEFAULT_BREAKER, help="breaker file (channel scaling, simulator)")
    p.add_argument("--host", default="127.0.0.1", help="listen address")
    p.add_argument("--seed", type=int, default=1)


def _load(args):
    from service.breaker_file import load_breaker

    from .scaling import ChannelScaling

    if not Path(args.breaker).is_file():
        raise ValueError(f"breaker file not found: {args.breaker}")
    breaker = load_breaker(args.breaker)
    return breaker, ChannelScaling.from_breaker(breaker)


def run_serial(args) -> int:
    from .emulators.serial_daq import FaultPlan, SerialDaqEmulator
    from .emulators.sources import emulator_source

    if args.duration <= 0:
        raise ValueError("--duration must be positive")
    breaker, scaling = _load(args)
    source = emulator_source(breaker, seed=args.seed, duration_s=args.duration, fs=scaling.sample_rate_hz,
                             script=args.script, return_shape=args.return_shape)
    faults = FaultPlan(corrupt_every=args.corrupt_every, drop_every=args.drop_every,
                       garbage_every=args.garbage_every, disconnect_every=args.disconnect_every)
    em = SerialDaqEmulator(source, link="pty" if args.pty else "tcp", scaling=scaling,
                           frame_samples=args.frame_samples, speed=args.speed or None,
                           host=args.host, port=args.port, faults=faults, seed=args.seed)
    with em:
        print(f"serial DAQ emulator streaming at {args.speed or 'max'} x real time; connect the driver to:")
        print(f"  {em.url}")
        print(f"  e.g. hvcb capture --driver serial --url {em.url} --out DIR", flush=True)
        em.start()
        try:
            while not em.done.wait(0.5):
                pass
        except KeyboardInterrupt:
            pass
    print(json.dumps(asdict(em.stats)))
    return 0


def _captures(breaker, scaling, n: int, seed: int):
    from drivers.synthetic import synthesize_capture

    from .emulators.sources import NOMINAL
    from .interface import SampleBlock

    rng = np.random.default_rng(seed)
    fs = scaling.sample_rate_hz
    for k in range(n):
        op = "open" if k % 2 == 0 else "close"
        cap, _ = synthesize_capture(breaker, op, NOMINAL[op], rng=rng, fs=fs)
        yield SampleBlock(int(k * 10 * fs), cap.travel, cap.vibration, fs)  # one operation per 10 s


def run_modbus(args) -> int:
    from .emulators.modbus_daq import ModbusDaqEmulator

    if args.captures < 0:
        raise ValueError("--captures must be >= 0")
    breaker, scaling = _load(args)
    em = ModbusDaqEmulator(_captures(breaker, scaling, args.captures, args.seed), transport=args.transport,
                           scaling=scaling, host=args.host, port=args.port, device_id=args.device_id)
    if args.delay_at:
        em.inject_delay(args.delay_s, at_read=args.delay_at)
    if args.exception_at:
        em.inject_exception(at_read=args.exception_at)

    async def serve():
        async with em:
            where = (f"--transport tcp --host {em.host} --port {em.port}" if args.transport == "tcp"
                     else f"--transport rtu --url {em.url}")
            print(f"Modbus DAQ emulator ({args.transport}, device id {args.device_id}) holding "
                  f"{args.captures} capture(s); connect the driver with:")
            print(f"  {where}", flush=True)
            done_at = None
            while True:
                await asyncio.sleep(0.2)
                if em.stats.captures_acknowledged >= args.captures and args.linger > 0:
                    done_at = done_at or time.monotonic()
                    if time.monotonic() - done_at >= args.linger:
                        return

    try:
        asyncio.run(serve())
    except KeyboardInterrupt:
        pass
    print(json.dumps(asdict(em.stats)))
    return 0
