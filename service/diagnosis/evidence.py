"""Stage 3 — evidence: posterior probabilities of the hypotheses under a noise model estimated
from the data in motion.

Noise model. The whitening of ``windows`` uses each capture's pre-trigger σ_i; in motion the
noise can be larger (vibration) and correlated. Both are estimated from the residual the most
flexible description leaves (the best catalogued hypothesis plus the discrepancy term with every
coefficient free, ``discrepancy.Discrepancy.ls_residuals``):

- scale φ = Σ e² / (n − p_states − k), the in-motion variance in units of the pre-trigger one;
- AR(1) coefficient ρ, the pooled lag-1 autocorrelation of those residuals. For a signature that
  is smooth on the block scale (every catalogued effect, the discrepancy's splines), pre-whitening
  by (1 − ρL) divides its χ² contribution by κ = (1 + ρ)/(1 − ρ) (the long-run variance of an
  AR(1), e.g. Hamilton 1994 §7.2) and leaves n/κ effectively independent blocks.

So s² = φ·κ and n_eff = n/κ. Each catalogued hypothesis H (k_H parameters beyond the states) gets
the Schwarz approximation of its marginal likelihood, with the noise scale profiled:

    ln p(D | H) ≈ −½ χ²_H / s² − ½ k_H ln n_eff,

and ``outside_catalogue`` the closed-form marginal likelihood of the discrepancy term added to
the best catalogued hypothesis (``discrepancy``, its amplitude marginalised). Detection is the
nested likelihood ratio these imply: no size gate; more captures give more evidence.

Priors (stated): none, outside_catalogue and each single family get equal prior weight; each
pair gets 1/F of it (F families), i.e. "two defects at once" is as likely a priori as one
particular defect.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .hypotheses import Fits


@dataclass
class Evidence:
    """Stage 3 result: per hypothesis name its log evidence, prior and posterior probability;
    the noise model (φ, ρ, s², n_eff) and the discrepancy's ln Bayes factor."""

    log_evidence: dict
    prior: dict
    probabilities: dict
    dispersion: float
    rho: float
    s2: float
    n: int
    n_eff: float
    log_bf_discrepancy: float

    @property
    def bic(self) -> dict:
        """−2 × the log evidence (with the predictive scores: −2 elpd, which carry no prior), the
        scale of a BIC."""
        return {k: float(-2.0 * (v - (np.log(self.prior[k]) if k in self.prior else 0.0)))
                for k, v in self.log_evidence.items()}

    def ranked(self):
        return sorted(self.probabilities.items(), key=lambda kv: -kv[1])


def lag1(residuals) -> float:
    """Pooled lag-1 autocorrelation of per-capture residual vectors."""
    num = den = 0.0
    for e in residuals:
        e = np.asarray(e, float) - float(np.mean(e))
        num += float(np.dot(e[:-1], e[1:]))
        den += float(np.dot(e, e))
    return num / den if den > 0 else 0.0


def evidence(fits: Fits, scores=None) -> Evidence:
    """The noise model's figures from the fits; the probabilities are the predictive weights of
    ``scores`` (``predictive``) when given, else the fits' own Schwarz evidence (the former
    method, kept for comparison)."""
    ev = _fits_evidence(fits)
    if scores is None:
        return ev
    return Evidence(dict(scores.elpd), {}, dict(scores.weights), ev.dispersion, ev.rho, ev.s2,
                    ev.n, ev.n_eff, ev.log_bf_discrepancy)


def _fits_evidence(fits: Fits) -> Evidence:
    n = fits.windows.n
    hyps = fits.hypotheses
    out = hyps["outside_catalogue"]
    disc = out.discrepancy
    res = disc.ls_residuals()
    p_state = sum(cw.Q.shape[1] for cw in fits.windows.captures)
    dof = max(n - p_state - disc.k - out.base_k, 1)
    phi = float(sum(float(np.sum(e * e)) for e in res) / dof)
    rho = max(lag1(res), 0.0)
    kappa = (1.0 + rho) / (1.0 - rho) if rho < 0.99 else 199.0
    s2 = max(phi, 1e-6) * kappa
    n_eff = n / kappa
    singles = [h for h in hyps.values() if len(h.effects) == 1 and not h.outside]
    F = max(len(singles), 1)
    prior = {name: (1.0 / F if len(h.effects) == 2 and not h.outside else 1.0) for name, h in hyps.items()}
    z = sum(prior.values())
    prior = {k: v / z for k, v in prior.items()}
    logev = {}
    for name, h in hyps.items():
        if h.outside:
            continue
        logev[name] = -0.5 * h.chi2 / s2 - 0.5 * h.k * np.log(n_eff) + np.log(prior[name])
    base = "+".join(out.effects) if out.effects else "none"
    lbf = disc.log_bf(s2)
    logev["outside_catalogue"] = logev[base] - np.log(prior[base]) + lbf + np.log(prior["outside_catalogue"])
    names = list(logev)
    v = np.array([logev[k] for k in names])
    w = np.exp(v - v.max())
    post = w / w.sum()
    return Evidence({k: float(logev[k]) for k in names}, prior, {k: float(p) for k, p in zip(names, post)},
                    phi, float(rho), float(s2), int(n), float(n_eff), float(lbf))
