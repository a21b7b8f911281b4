"""next_measurement: which additional recording would separate the leading rivals best.

For two rival hypotheses a and b fitted on these captures, the recording's predicted whitened
signatures s_a and s_b are computed (each capture's state changed as the recording would change
it), b's strength is rescaled to mimic a as well as it can (and vice versa), and what neither
the states nor that rescaling can absorb is the expected χ² difference the recording adds:

    E[ΔBIC] ≈ M · min_c Σ_i ‖P⊥_i (s_a,i − c·s_b,i)‖²        (M recordings like these),

the noise adding the same expected amount to both. Candidates: more operations under other
conditions (colder: buffer oil +20 % damping, friction +15 %; warmer: −15 %, −10 %), the same
conditions again, the other operation, a contact-side travel sensor. A lower control voltage
changes the latch release, which the catalogue's models do not describe: not offered.
"""

from __future__ import annotations

import numpy as np

from ..mechanics.effects import OPERATIONS
from .data import STATE, WindowData, design_state
from .hypotheses import Fits, signature
from .windows import linearise

MORE = 5   # recordings per proposal
CONDITIONS = {  # relative change of the reduced state a condition causes
    "colder": {"open": {"DO": 1.20, "BO": 0.99}, "close": {"CC": 1.05}},
    "warmer": {"open": {"DO": 0.85, "BO": 1.01}, "close": {"CC": 0.97}},
}


def _separation(caps, sa, sb) -> float:
    best = np.inf
    for u, v in ((sa, sb), (sb, sa)):
        num = sum(float(np.dot(cw.project_out(a), cw.project_out(b))) for cw, a, b in zip(caps, u, v))
        den = sum(float(np.sum(cw.project_out(b) ** 2)) for cw, b in zip(caps, v))
        c = max(num / den, 0.0) if den > 0 else 0.0
        best = min(best, sum(float(np.sum(cw.project_out(a - c * b) ** 2)) for cw, a, b in zip(caps, u, v)))
    return float(best)


def next_measurement(fits: Fits, rivals: list) -> list:
    names = [r["effect"] for r in rivals if r["effect"] in fits.hypotheses
             and fits.hypotheses[r["effect"]].effects and not fits.hypotheses[r["effect"]].outside]
    if len(names) < 2:
        return []
    ha, hb = fits.hypotheses[names[0]], fits.hypotheses[names[1]]
    w = fits.windows
    op, br, caps = w.operation, w.breaker, w.captures
    N = len(caps)
    out = []
    # every proposal is predicted at the same (reduced) states, so that they compare
    sa = [signature(cw, op, br, ha.as_effects()) for cw in caps]
    sb = [signature(cw, op, br, hb.as_effects()) for cw in caps]
    out.append({"measurement": f"{MORE} more {op} operations under the same conditions",
                "expected_delta_bic": MORE / N * _separation(caps, sa, sb), "separates": [names[0], names[1]]})
    for cond, change in CONDITIONS.items():
        ch = change[op]
        xs = []
        for cw in caps:
            x = cw.x.copy()
            for k, f in ch.items():
                x[STATE[op].index(k)] *= f
            xs.append(x)
        pa = [signature(cw, op, br, ha.as_effects(), x=x) - signature(cw, op, br, (), x=x) for cw, x in zip(caps, xs)]
        pb = [signature(cw, op, br, hb.as_effects(), x=x) - signature(cw, op, br, (), x=x) for cw, x in zip(caps, xs)]
        label = "colder (buffer oil thicker, more friction)" if cond == "colder" else "warmer (oil thinner)"
        out.append({"measurement": f"{MORE} more {op} operations {label}",
                    "expected_delta_bic": MORE / N * _separation(caps, pa, pb), "separates": [names[0], names[1]]})
    other = "close" if op == "open" else "open"
    # the other operation only where the breaker file describes it (a closing needs its cam)
    if all(other in OPERATIONS[e] for e in ha.effects + hb.effects) and (other == "open" or br.cam is not None):
        d = design_window(br, other, caps[0].data.noise)
        cw = linearise(d[0], d[1], br, other)
        pa = [signature(cw, other, br, ha.as_effects())]
        pb = [signature(cw, other, br, hb.as_effects())]
        out.append({"measurement": f"{MORE} {'closing' if other == 'close' else 'opening'} operations",
                    "expected_delta_bic": MORE * _separation([cw], pa, pb), "separates": [names[0], names[1]]})
    pa = [signature(cw, op, br, ha.as_effects(), sensor_side=True) for cw in caps]
    pb = [signature(cw, op, br, hb.as_effects(), sensor_side=True) for cw in caps]
    out.append({"measurement": f"{MORE} more {op} operations with a contact-side travel sensor",
                "expected_delta_bic": MORE / N * _separation(caps, pa, pb), "separates": [names[0], names[1]]})
    return sorted(out, key=lambda m: -m["expected_delta_bic"])


def design_window(breaker, operation, noise):
    """A noise-free window of ``operation`` at the breaker's design state (8 kHz blocks)."""
    from .data import model_curve
    design = breaker.design_parameters()
    x = np.append(design_state(breaker, operation), 0.0)
    t = np.arange(0.0, 0.06, 16 / 128_000)
    d = WindowData(t, np.zeros_like(t), np.full(t.size, 16.0), noise, 0.0, float(design["DC"]), "design")
    d.y = model_curve(x, d, breaker, operation)
    return x, d
