"""Stage 6 — the decision, from the answer's set (``answer_set``) alone.

1. The status is the set's: ``none`` / ``named`` / ``unexplained`` when a set of one is stated
   (Learn then Test's threshold reached), else ``ambiguous``; the answer is the most probable
   hypothesis and its probability the scorer's (``scorer``), with nothing renormalised.
2. The rivals are the set's other members, with their probabilities.
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
from .answer_set import AnswerSet
from .data import STATE
from .evidence import Evidence
from .hypotheses import Fits, n_params, signature


@dataclass
class Decision:
    status: str
    hypothesis: str          # the answer's hypothesis name
    effects: list
    rivals: list
    absorbed: list
    gap_sigma: float
    answer: str = "none"
    answer_probability: float = 0.0      # the scorer's
    raw_probability: float = 0.0         # the same (kept for the older readers of the result)
    probabilities: dict = None
    calibration: str = "scorer"
    set: AnswerSet = None


def gap_sigma(chi2: float, n: int, block: float) -> float:
    """The model misfit per sample in units of σ from a whitened χ² over n block means of
    ``block`` samples each."""
    return float(np.sqrt(max(chi2 / n - 1.0, 0.0) / block))


def decide(fits: Fits, ev: Evidence, aset: AnswerSet, catalogue, strengths=None) -> Decision:
    hyps = fits.hypotheses
    g0 = gap_sigma(hyps["none"].chi2 / ev.dispersion, ev.n, fits.windows.block)
    absorbed = absorbed_effects(fits, catalogue, ev, strengths)
    top = aset.top
    rivals = [{"effect": k, "probability": aset.probabilities[k]} for k in aset.members if k != top]
    effects = list(top.split("+")) if aset.status == "named" else []
    if not aset.named:
        rivals = [{"effect": k, "probability": aset.probabilities[k]} for k in aset.members]
    return Decision(aset.status, top, effects, rivals, absorbed, g0, top, aset.probability, aset.probability,
                    aset.probabilities, "scorer", aset)


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
