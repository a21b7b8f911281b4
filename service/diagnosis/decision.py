"""Stage 4 — the one decision rule.

1. Name the hypothesis whose posterior probability reaches ``P_NAME`` (``none``, one effect,
   a pair, or ``outside_catalogue`` → status ``unexplained``).
2. Otherwise ``ambiguous``, with the rivals (every hypothesis above ``P_RIVAL``) — unless the
   whole gap is below what matters (``MILD``): then the answer is ``none`` and the leading
   effects are listed as present but mild. A gap too small to matter is never ``unexplained``.
3. The size of each effect: its fitted contribution (the part of its signature the state cannot
   absorb, rms per sample) against ``MILD``·σ: below it the effect is reported ``mild``, not
   named (a pair whose second effect is mild names the first only).
4. Absorbed: a catalogued effect at its realistic strength whose unabsorbed part could not pay
   its own BIC price (χ² < k ln n over these captures) is listed with the bias it causes in the
   reduced parameters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..prototypes.a import REALISTIC, shape_defaults
from .data import BLOCK, STATE
from .evidence import Evidence
from .hypotheses import Fits, n_params, signature

P_NAME = 0.9                 # stated level: an answer is given when its probability reaches it
P_RIVAL = 0.05               # rivals listed in an ambiguous answer
MILD = 1.0 / np.sqrt(BLOCK)  # a misfit below σ/√16 (the sd of one block mean) is invisible in any block


@dataclass
class Decision:
    status: str
    hypothesis: str          # the most probable hypothesis (whose probability is the stated one)
    effects: list
    rivals: list
    mild: list
    absorbed: list
    gap_sigma: float


def contribution_sigma(h, fits: Fits, effect: str | None = None) -> float:
    """rms per sample of the fitted effect's (or of one of a pair's effects') unabsorbed
    signature, in units of σ."""
    if not h.effects:
        return 0.0
    w = fits.windows
    tot, cnt = 0.0, 0
    for i, cw in enumerate(h.captures):
        if effect is None:
            s = h.signatures[i]
        else:
            s = signature(cw, w.operation, w.breaker, [x for x in h.as_effects() if x[0] == effect])
        tot += float(np.sum(cw.project_out(s) ** 2)) / BLOCK
        cnt += s.size
    return float(np.sqrt(tot / max(cnt, 1)))


def gap_sigma(chi2: float, n: int) -> float:
    """The model misfit per sample in units of σ from a whitened χ² over n block means."""
    return float(np.sqrt(max(chi2 / n - 1.0, 0.0) / BLOCK))


def decide(fits: Fits, ev: Evidence, catalogue) -> Decision:
    hyps = fits.hypotheses
    ranked = ev.ranked()
    top, p_top = ranked[0]
    g0 = gap_sigma(hyps["none"].chi2, ev.n)
    absorbed = absorbed_effects(fits, catalogue, ev.n)
    rivals = [{"effect": k, "probability": p} for k, p in ranked if p >= P_RIVAL][:4]
    if p_top >= P_NAME:
        h = hyps[top]
        if top == "none":
            return Decision("none", top, [], [], [], absorbed, g0)
        if top == "outside_catalogue":
            if g0 < MILD:
                return Decision("none", top, [], [], _mild(fits, ranked), absorbed, g0)
            return Decision("unexplained", top, [], rivals[1:], [], absorbed, g0)
        size = {e: contribution_sigma(h, fits, e) for e in h.effects}
        strong = [e for e in h.effects if size[e] >= MILD]
        mild = [e for e in h.effects if size[e] < MILD]
        if not strong:
            return Decision("none", top, [], [], mild, absorbed, g0)
        return Decision("named", top, strong, [], mild, absorbed, g0)
    if g0 < MILD:
        return Decision("none", top, [], [], _mild(fits, ranked), absorbed, g0)
    return Decision("ambiguous", top, [], rivals, [], absorbed, g0)


def _mild(fits, ranked):
    out = []
    for k, p in ranked:
        h = fits.hypotheses[k]
        if h.outside or not h.effects:
            continue
        for e in h.effects:
            if e not in out:
                out.append(e)
        if len(out) >= 2:
            break
    return out


def absorbed_effects(fits: Fits, catalogue, n: int):
    """Effects the reduced parameters soak up at realistic strength on these captures."""
    w = fits.windows
    out = []
    for e in catalogue:
        eff = [(e, REALISTIC[e], shape_defaults(e))]
        chi, bias = 0.0, []
        for cw in w.captures:
            s = signature(cw, w.operation, w.breaker, eff)
            chi += float(np.sum(cw.project_out(s) ** 2))
            bias.append(cw.state_step(s) / np.where(cw.x == 0, 1.0, cw.x))
        if chi < n_params(e) * np.log(n):
            b = np.mean(bias, axis=0)
            names = STATE[w.operation]
            out.append({"effect": e, "parameter_bias": {k: float(v) for k, v in zip(names, b[:len(names)])},
                        "unabsorbed_chi2": chi})
    return out
