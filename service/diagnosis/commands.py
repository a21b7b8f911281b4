"""``hvcb diagnose CAP… --breaker FILE --operation open|close [--json] [--plot PNG]``.

CAP may be capture files, a directory (every .cfg/.cff/.csv in it) or a glob; several captures
are one breaker, diagnosed jointly."""

from __future__ import annotations

import glob
import json
from pathlib import Path

CAPTURE_SUFFIXES = (".cfg", ".cff", ".csv")


def register(subparsers) -> None:
    p = subparsers.add_parser("diagnose", help="where the reduced model misses, which physical "
                              "effect explains it, and how far it shrinks (several captures = one breaker)")
    p.add_argument("captures", nargs="+", help="capture files, a directory or a glob (quoted) of one operation")
    p.add_argument("--breaker", required=True, help="breaker file (TOML)")
    p.add_argument("--operation", required=True, choices=("open", "close"))
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", help="write the residual-by-phase plot (first capture) to this PNG")
    p.add_argument("--seed", type=int, default=1)
    p.set_defaults(func=run_diagnose)


def expand(args_captures) -> list:
    """Capture paths from files, directories and globs, in a stable order; raises
    DiagnosisError (in words) when one names nothing."""
    from .errors import DiagnosisError

    out = []
    for a in args_captures:
        p = Path(a)
        if p.is_dir():
            found = sorted(str(f) for f in p.iterdir() if f.suffix.lower() in CAPTURE_SUFFIXES)
            if not found:
                raise DiagnosisError(f"{a}: the directory holds no capture (.cfg, .cff or .csv)")
            out += found
        elif p.exists():
            out.append(str(p))
        elif any(ch in a for ch in "*?["):
            found = sorted(f for f in glob.glob(a) if Path(f).suffix.lower() in CAPTURE_SUFFIXES)
            if not found:
                raise DiagnosisError(f"{a}: the pattern matches no capture file")
            out += found
        else:
            raise DiagnosisError(f"{a}: no such file or directory")
    return list(dict.fromkeys(out))


def run_diagnose(args) -> int:
    from ..acquisition.capture_file import breaker_reading, read_capture
    from ..breaker_file import load_breaker, load_effect_strengths
    from ..estimation.record import operation_capture
    from .diagnose import diagnose
    from .errors import DiagnosisError

    if args.plot:
        from service.plots import require_matplotlib

        require_matplotlib("--plot")  # before the work, not after it
    breaker = load_breaker(args.breaker)
    paths = expand(args.captures)
    caps = [read_capture(c, **breaker_reading(breaker)) for c in paths]
    # An analyser record (coil currents, no vibration) holds a close-open sequence: diagnose the
    # asked operation cut from it, as `hvcb fit --operation` fits it.
    try:
        caps = [operation_capture(c, breaker, args.operation)[0] for c in caps]
    except ValueError as exc:
        raise DiagnosisError(str(exc)) from None
    result = diagnose(caps, breaker, args.operation, seed=args.seed, strengths=load_effect_strengths(args.breaker))
    if args.plot:
        _plot(result, caps[0], breaker, args)
    if args.json:
        print(json.dumps(result, default=_jsonable, indent=1))
    else:
        from .report import format_report
        print(format_report(result))
    return 0


def _plot(result, cap, breaker, args):
    import numpy as np

    from .data import STATE, model_curve
    from .report import plot_residuals
    from .windows import prepare

    w = prepare([cap], breaker, args.operation, seed=args.seed)
    cw = w.captures[0]
    d = cw.data
    before = d.y - model_curve(cw.x, d, breaker, args.operation)
    after = None
    named = result.get("named") or []
    if named:
        p = result["corrected_parameters"][0]
        x1 = np.array([p[k] for k in STATE[args.operation]] + [p["onset_delay_s"]])
        eff = [(n["effect"], n["strength"], list(n["shape"].values())) for n in named]
        after = d.y - model_curve(x1, d, breaker, args.operation, eff)
    plot_residuals(result, before, after, d.t + d.t_start, args.plot)


def _jsonable(v):
    import numpy as np

    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.ndarray):
        return v.tolist()
    raise TypeError(type(v))
