"""Stage 4 — the one decision rule, from the evidence alone.

1. The answer is the most probable hypothesis: ``none`` (P(no effect)), one effect, a pair, or
   ``outside_catalogue``. Its raw probability goes through the calibration map
   (``calibration``) and the table is renormalised around it: one number everywhere (a share
   the calibration cannot attribute to an alternative is listed as ``unattributed``).
2. It is stated (status ``none`` / ``named`` / ``unexplained``) when that probability reaches
   ``P_NAME``; otherwise ``ambiguous`` with the rivals (every hypothesis above ``P_RIVAL``) and the
   measurement that would separate the first two.
3. Size never changes the status: it is reported as ``materiality`` (report), with a flag
   ``material`` when the effect's unabsorbed part exceeds the sd of one block mean.
4. Absorbed: a catalogued effect at the breaker's typical strength whose unabsorbed part could not
   pay its own evidence price (χ² < k ln n_eff) is listed with the bias it puts into the reduced
   parameters: the reduced model's own terms (viscous friction ≈ CO) end here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics.effects import REFERENCE_STRENGTHS, shape_defaults
from .calibration import UNATTRIBUTED, calibrate, renormalise
from .data import STATE
from .evidence import Evidence
from .hypotheses import Fits, n_params, signature

# The stated level: an answer is given when its probability reaches it (the acceptance
# reads calibration at ≥ 0.9; a lower level would state answers the calibration cannot back).
P_NAME = 0.9
P_RIVAL = 0.05     # rivals listed in an ambiguous answer: a 1-in-20 alternative is worth a measurement


@dataclass
class Decision:
    status: str
    hypothesis: str          # the answer's hypothesis name
    effects: list
    rivals: list
    absorbed: list
    gap_sigma: float
    answer: str = "none"
    answer_probability: float = 0.0      # calibrated
    raw_probability: float = 0.0         # the evidence's
    probabilities: dict = None           # renormalised around the calibrated answer
    calibration: str = "identity"


def gap_sigma(chi2: float, n: int, block: float) -> float:
    """The model misfit per sample in units of σ from a whitened χ² over n block means of
    ``block`` samples each."""
    return float(np.sqrt(max(chi2 / n - 1.0, 0.0) / block))


def decide(fits: Fits, ev: Evidence, catalogue, strengths=None) -> Decision:
    hyps = fits.hypotheses
    g0 = gap_sigma(hyps["none"].chi2 / ev.dispersion, ev.n, fits.windows.block)
    absorbed = absorbed_effects(fits, catalogue, ev, strengths)
    top, p_raw = ev.ranked()[0]
    p_cal, method = calibrate(p_raw)
    probs = renormalise(ev.probabilities, top, p_cal)
    ranked = sorted(((k, p) for k, p in probs.items() if k != UNATTRIBUTED), key=lambda kv: -kv[1])
    rivals = [{"effect": k, "probability": p} for k, p in ranked if p >= P_RIVAL][:4]
    h = hyps[top]
    if p_cal >= P_NAME:
        status = {"none": "none", "outside_catalogue": "unexplained"}.get(top, "named")
        effects = list(h.effects) if status == "named" else []
        rivals = rivals[1:]
    else:
        status, effects = "ambiguous", []
    return Decision(status, top, effects, rivals, absorbed, g0, top, p_cal, p_raw, probs, method)


def absorbed_effects(fits: Fits, catalogue, ev: Evidence, strengths=None):
    """Effects the reduced parameters soak up at the breaker's typical strength on these
    captures, with the relative bias they put into each parameter."""
    w = fits.windows
    strengths = strengths or REFERENCE_STRENGTHS
    out = []
    for e in catalogue:
        eff = [(e, strengths[e], shape_defaults(e))]
        chi, bias = 0.0, []
        for cw in w.captures:
            s = signature(cw, w.operation, w.breaker, eff)
            chi += float(np.sum(cw.project_out(s) ** 2))
            bias.append(cw.state_step(s) / np.where(cw.x == 0, 1.0, cw.x))
        if chi / ev.s2 < n_params(e) * np.log(ev.n_eff):
            b = np.mean(bias, axis=0)
            names = STATE[w.operation]
            out.append({"effect": e, "strength": float(strengths[e]),
                        "bias": {k: float(v) for k, v in zip(names, b[:len(names)])},
                        "unabsorbed_chi2": chi / ev.s2})
    return out
