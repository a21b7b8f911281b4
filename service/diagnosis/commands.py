"""``hvcb diagnose CAPTURE [CAPTURE ...] --breaker FILE --operation open|close [--json] [--plot PNG]``."""

from __future__ import annotations

import json

import numpy as np


def register(subparsers) -> None:
    p = subparsers.add_parser("diagnose", help="where the reduced model misses, which physical "
                              "effect explains it, and how far it shrinks")
    p.add_argument("captures", nargs="+", help="capture files (.cfg/.cff/.csv) of one operation")
    p.add_argument("--breaker", required=True, help="breaker file (TOML)")
    p.add_argument("--operation", required=True, choices=("open", "close"))
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", help="write the residual-by-phase plot to this PNG")
    p.add_argument("--seed", type=int, default=1)
    p.set_defaults(func=run_diagnose)


def run_diagnose(args) -> int:
    from ..acquisition.capture_file import read_capture
    from ..breaker_file import load_breaker
    from .diagnose import diagnose

    if args.plot:
        from service.plots import require_matplotlib

        require_matplotlib("--plot")  # before the work, not after it
    breaker = load_breaker(args.breaker)
    caps = [read_capture(c, travel_channel=breaker.channels["travel"],
                         vibration_channel=breaker.channels["vibration"]) for c in args.captures]
    result = diagnose(caps, breaker, args.operation, seed=args.seed)
    if args.plot:
        _plot(result, caps[0], breaker, args)
    if args.json:
        print(json.dumps(result, default=_jsonable, indent=1))
    else:
        from .report import format_report
        print(format_report(result))
    return 0


def _plot(result, cap, breaker, args):
    from ..estimation import fit_capture
    from .augmented import Fit
    from .data import STATE, model_curve, window_data
    from .report import plot_residuals

    fr = fit_capture(cap, breaker, args.operation, seed=args.seed)
    d = window_data(cap, fr, breaker, args.operation)
    c0 = result["captures"][0]
    x0 = np.array([c0["reduced_parameters"][k] for k in STATE[args.operation]] + [c0["onset_delay_s"]])
    before = d.y - model_curve(x0, d, breaker, args.operation, None)[0]
    after = None
    hf = result.get("how_far")
    if hf:
        x1 = np.array([hf["corrected_parameters"][k] for k in STATE[args.operation]] + [hf["onset_delay_s"]])
        f = Fit(x1, hf["strength"], hf["effect"])
        after = d.y - model_curve(f.x, d, breaker, args.operation, f.effect, f.strength)[0]
    plot_residuals(result, before, after, d.t + d.t_start, args.plot)


def _jsonable(v):
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, np.bool_):
        return bool(v)
    raise TypeError(type(v))
