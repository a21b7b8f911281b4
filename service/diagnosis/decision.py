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

from ..mechanics.effects import REFERENCE_STRENGTHS as REALISTIC, shape_defaults
from .data import BLOCK, STATE
from .evidence import Evidence
from .hypotheses import Fits, n_params, signature

P_NAME = 0.9                 # stated level: an answer is given when its probability reaches it
P_RIVAL = 0.05               # rivals listed in an ambiguous answer
P_TRACE = 1e-3               # hypotheses below this are not sized (their answer is their effects)
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
    answers: dict = None        # {answer: pooled probability}
    answer: str = "none"        # the answer whose probability is stated
    answer_probability: float = 0.0


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
    """The one rule (module docstring). Hypotheses that give the same answer — the same strong
    effects, their other effects mild — pool their probability: "orifice buffer, plus a trace
    of Stribeck friction" and "orifice buffer, plus a trace of puffer" both answer orifice."""
    hyps = fits.hypotheses
    g0 = gap_sigma(hyps["none"].chi2, ev.n)
    absorbed = absorbed_effects(fits, catalogue, ev.n)
    answers, best_h, mild_of = {}, {}, {}
    for name, p in ev.ranked():
        h = hyps[name]
        if name in ("none", "outside_catalogue"):
            a, mild = name, []
        elif p < P_TRACE:
            a, mild = "+".join(sorted(h.effects)), []
        else:
            size = {e: contribution_sigma(h, fits, e) for e in h.effects}
            strong = sorted(e for e in h.effects if size[e] >= MILD)
            a, mild = ("+".join(strong) or "none"), [e for e in h.effects if size[e] < MILD]
        answers[a] = answers.get(a, 0.0) + p
        if a not in best_h:
            best_h[a], mild_of[a] = name, mild
    ranked = sorted(answers.items(), key=lambda kv: -kv[1])
    top, p_top = ranked[0]
    rivals = [{"effect": k, "probability": p} for k, p in ranked if p >= P_RIVAL][:4]
    if p_top >= P_NAME:
        if top == "none":
            return Decision("none", best_h[top], [], [], mild_of[top], absorbed, g0, answers, top, p_top)
        if top == "outside_catalogue":
            if g0 < MILD:
                return Decision("none", best_h[top], [], [], _mild(fits, ev.ranked()), absorbed, g0, answers,
                                "none", p_top)
            return Decision("unexplained", best_h[top], [], rivals[1:], [], absorbed, g0, answers, top, p_top)
        return Decision("named", best_h[top], top.split("+"), [], mild_of[top], absorbed, g0, answers, top, p_top)
    if g0 < MILD:
        return Decision("none", "none", [], [], _mild(fits, ev.ranked()), absorbed, g0, answers, "none",
                        answers.get("none", 0.0))
    return Decision("ambiguous", best_h[top], [], rivals, [], absorbed, g0, answers, top, p_top)


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
