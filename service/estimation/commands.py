"""``hvcb fit``: estimate the model parameters of one captured operation."""

from __future__ import annotations

import json
import sys

from service.arguments import rate_hz  # (--rate)

from ..errors import UserError

DEFAULT_BREAKER = "config/breakers/reference-252kV.toml"


def register(subparsers) -> None:
    p = subparsers.add_parser("fit", help="fit the dynamic model to one captured operation")
    p.add_argument("capture", help="COMTRADE .cfg (with its .dat) or CSV t_s,travel_rad[,vibration_g]")
    p.add_argument("--breaker", default=DEFAULT_BREAKER, help="breaker file (TOML)")
    p.add_argument("--operation", required=True, choices=("open", "close"))
    p.add_argument("--dc", type=float, default=None,
                   help="closing only: DC = AO [s^-2] from the latest opening fit (default: breaker file)")
    p.add_argument("--index", type=int, default=0,
                   help="in a record of several operations (an analyser's CO or O-CO test), which one "
                        "of the --operation kind to fit, counting from 0 (default 0)")
    p.add_argument("--rate", type=rate_hz, default=None,
                   help="sampling rate of a bare analyser export that states none [Hz; 10k = 10 kS/s]")
    p.add_argument("--seed", type=int, default=1, help="CMA-ES seed (explicit; default 1)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run_fit)


def run_fit(args) -> int:
    # Imported here, not at the top: `hvcb fit --help` must not load CMA-ES, scipy and numba.
    from drivers.capture import CaptureError

    from ..acquisition.capture_file import breaker_reading, read_capture
    from ..breaker_file import BreakerFileError, load_breaker
    from .fit import fit_capture
    from .window import FitError

    try:
        breaker = load_breaker(args.breaker)
        capture = read_capture(args.capture, **breaker_reading(breaker), rate=args.rate)
        result = fit_capture(capture, breaker, args.operation, dc=args.dc, seed=args.seed, index=args.index)
    except (BreakerFileError, CaptureError, FitError) as exc:
        raise UserError(str(exc)) from None
    except (ValueError, FloatingPointError) as exc:  # numpy's LinAlgError is a ValueError
        if not _non_finite(exc):
            raise
        # a NaN or ∞ met inside a library (scipy's "array must not contain infs or NaNs"): in words
        raise UserError(f"{args.capture}: the {args.operation} fit met a value it cannot compute (a NaN or an "
                        "infinity) on its path; the record holds a missing, over-range or out-of-scale sample "
                        "that the reader did not mask (run hvcb inspect on it to see its channels)") from None
    if args.json:
        # whole or nothing: a value JSON cannot hold must not leave half an object on stdout
        text = json.dumps(result.to_dict(), allow_nan=False, default=_finite)  # to_dict is finite already
        sys.stdout.write(text + "\n")
        return 0
    print(format_fit(result))
    return 0


def _non_finite(exc: BaseException) -> bool:
    text = str(exc).lower()
    return any(w in text for w in ("nan", "inf", "not finite", "non-finite"))


def _finite(value):
    return None


def format_fit(result) -> str:
    """A plain table for the terminal."""
    lines = [f"{result.operation} fit: RMSE {result.rmse_rad * 1e3:.3f} mrad "
             f"(noise {result.noise_rad * 1e3:.3f} mrad), F = {result.fitness:.1f}, "
             f"{result.evaluations} evaluations, {result.runtime_s * 1e3:.0f} ms",
             f"window {result.window_s[0] * 1e3:.3f}–{result.window_s[1] * 1e3:.3f} ms, "
             f"onset delay {result.onset_delay_s * 1e3:.3f} ms",
             f"{'param':<6}{'value':>14}{'95% CI':>30}{'±%':>8}"]
    for name, value in result.parameters.items():
        lo, hi = result.ci95[name]
        pct = 100 * (hi - lo) / 2 / abs(value) if value else float("nan")
        lines.append(f"{name:<6}{value:>14.4f}{f'[{lo:.4f}, {hi:.4f}]':>30}{pct:>8.3f}")
    n = result.interval_noise or {}
    if n.get("basis") == "residual in motion":
        widest = max(n["widening"].items(), key=lambda kv: kv[1])
        lines.append(f"95% CI from the residual in motion (its AR({n['ar_order']}) correlation, "
                     f"{n['band_rad'] * 1e3:.3f} mrad rms): up to {widest[1]:.1f}x the idle-noise "
                     f"interval ({widest[0]})")
    b = result.model_bias
    if b is not None:
        pct = {k: 100 * v / abs(result.parameters[k]) for k, v in b["effect_bound"].items() if result.parameters.get(k)}
        most = max(pct.items(), key=lambda kv: kv[1]) if pct else None
        lines.append(f"model bias (not in the CI): {b['rms_rad'] * 1e3:.3f} mrad rms repeats, "
                     f"{b['rms_over_noise']:.2f}x the noise, from {b['basis']}"
                     + (f"; it could move {most[0]} by at most ±{most[1]:.2f} %" if most else ""))
    if result.operation == "close":
        lines.append(f"DC = {result.dc_used:.2f} s^-2 from the {result.dc_source}")
    for name, est in result.structure.items():
        lo, hi = est["ci95"]
        lines.append(f"{name:<6}{est['value']:>14.4f}{f'[{lo:.4f}, {hi:.4f}]':>30}  (estimated from the curve)")
    if result.characteristics_record:
        c = result.characteristics_record
        lines.append(f"in the record's unit ({c.get('channel')}): stroke {c['stroke_mm']:.1f} mm, max travel "
                     f"{c['max_travel_mm']:.1f} mm, overtravel {c['overtravel_mm']:.1f} mm, rebound "
                     f"{c['rebound_mm']:.1f} mm, average speed {c['average_speed_m_s']:.2f} m/s, operating time "
                     f"{c['operating_time_s'] * 1e3:.1f} ms")
    if result.picked:
        p = result.picked
        lines.append(f"fitted {p['operation']} {p['index']} of {p['of']} in a record of "
                     f"{'-'.join(o[0].upper() for o in p['record_operations'])}")
    for w in result.warnings:
        lines.append(f"warning: {w}")
    return "\n".join(lines)
