"""Local sensitivity of the travel curve to each parameter (paper Table 5).

Each parameter p_i is perturbed by ±5 % around the reference breaker's design value, the others
fixed, and

    S_i = (1/N)·Σ_j |(y_j(p + Δp) − y_j(p)) / y_j(p)| / (|Δp| / p)

over the N samples of the nominal valid window (128 kHz, motion onset to the nominal peak).
y is the operation's own coordinate: the opening angle θ, or the closing θ2 (0 = open).
Samples where the nominal curve is close to zero (|y_j(p)| < 1 % of max |y|) are excluded: there
the relative change is 0/0 and would dominate the mean (the first ~0.2 ms of an opening and the
cam dwell of a closing, where θ2 has not moved yet). Closings keep DC at the design AO.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..mechanics.breaker import CLOSING_PARAMETERS, OPENING_PARAMETERS
from ..mechanics.closing import simulate_closing
from ..mechanics.opening import simulate_opening
from . import report
from .common import load_reference
from .synthetic_sets import operation_params

NAME = "sensitivity"
PAPER = {"AO": 1.21, "BO": 1.13, "DO": 0.94, "EO": 0.89, "AC": 1.26, "BC": 1.17, "CC": 1.09}
STEP = 0.05              # relative perturbation Δp/p
NEAR_ZERO = 0.01         # exclude samples with |y| below this fraction of max |y|
FS = 128_000.0


def _simulate(breaker, operation, params, t):
    p = operation_params(params, operation)
    if operation == "open":
        return simulate_opening(p, t, CO=breaker.CO, alpha0=breaker.alpha0).raise_for_status()
    return simulate_closing(p, t, cam=breaker.cam, geometry=breaker.closing_geometry).raise_for_status()


def sensitivity_coefficients(breaker, operation: str, params: dict, *, step: float = STEP,
                             fs: float = FS) -> dict:
    """S_i for +step and −step per parameter of ``operation`` (dimensionless).

    Returns {name: {"plus", "minus", "mean"}} and the sample counts used.
    """
    probe = _simulate(breaker, operation, params, np.arange(0.0, 0.2, 1 / fs))
    t = np.arange(0.0, probe.t_peak, 1 / fs)
    y0 = _simulate(breaker, operation, params, t).theta
    keep = np.abs(y0) >= NEAR_ZERO * np.max(np.abs(y0))
    names = OPENING_PARAMETERS if operation == "open" else CLOSING_PARAMETERS
    out = {}
    for name in names:
        s = {}
        for label, sign in (("plus", 1.0), ("minus", -1.0)):
            p = dict(params)
            p[name] = params[name] * (1.0 + sign * step)
            if operation == "open" and name == "AO":
                p["DC"] = params["DC"]   # DC belongs to the closing; keep it at design
            y = _simulate(breaker, operation, p, t).theta
            s[label] = float(np.mean(np.abs((y[keep] - y0[keep]) / y0[keep])) / step)
        s["mean"] = 0.5 * (s["plus"] + s["minus"])
        out[name] = s
    return {"coefficients": out, "samples": int(t.size), "samples_used": int(keep.sum()),
            "window_s": float(probe.t_peak)}


def run(out_dir: Path, *, seed: int = 2026, quick: bool = False) -> dict:
    """Table 5 for the reference breaker (deterministic: ``seed`` and ``quick`` are unused)."""
    t0 = time.perf_counter()
    breaker = load_reference()
    params = breaker.design_parameters()
    results = {op: sensitivity_coefficients(breaker, op, params) for op in ("open", "close")}
    coeff = {**results["open"]["coefficients"], **results["close"]["coefficients"]}
    data = {"study": NAME, "step": STEP, "near_zero_fraction": NEAR_ZERO, "sample_rate_hz": FS,
            "design_parameters": params, "results": results, "coefficients": coeff,
            "paper": PAPER, "runtime_s": time.perf_counter() - t0}
    report.write_json(out_dir, NAME, data)
    names = list(coeff)
    rows = [["S (+5 %)"] + [coeff[n]["plus"] for n in names],
            ["S (−5 %)"] + [coeff[n]["minus"] for n in names],
            ["S (mean)"] + [coeff[n]["mean"] for n in names],
            ["paper (Table 5)"] + [PAPER[n] for n in names]]
    notes = [f"Reference breaker design values; y is θ (opening) or θ2 (closing) at {FS / 1e3:.0f} kHz "
             "over the nominal valid window (motion onset to peak: "
             f"{results['open']['window_s'] * 1e3:.1f} ms opening, "
             f"{results['close']['window_s'] * 1e3:.1f} ms closing). Samples with |y| < "
             f"{NEAR_ZERO:.0%} of max |y| are excluded ({results['open']['samples'] - results['open']['samples_used']} "
             f"opening, {results['close']['samples'] - results['close']['samples_used']} closing samples)."]
    report.write_markdown(out_dir, NAME, "Sensitivity coefficients (paper Table 5)", rows,
                          ["coefficient"] + names, notes=notes, digits=3)
    _plot(out_dir, names, coeff)
    return {k: v for k, v in data.items() if k != "results"}


def _plot(out_dir, names, coeff):
    fig, ax = report.new_figure(figsize=(7, 3.5))
    x = np.arange(len(names))
    ax.bar(x - 0.2, [coeff[n]["mean"] for n in names], 0.4, label="this model")
    ax.bar(x + 0.2, [PAPER[n] for n in names], 0.4, label="paper Table 5")
    ax.set_xticks(x, names)
    ax.set_ylabel("S_i (mean of ±5 %)")
    ax.legend()
    report.save_figure(fig, Path(out_dir) / f"{NAME}.png")
