"""Stage 3 — evidence: posterior probabilities of the hypotheses.

Each hypothesis H gets the BIC (Schwarz) approximation of its marginal likelihood,

    ln p(D | H) ≈ −½ (χ²_H / φ + k_H ln n) + ln prior(H),

with n the number of blocks over all captures and k_H its free parameters beyond the reduced
model (each shape parameter paid for). φ ≥ 1 is the dispersion: χ² per degree of freedom of the
most flexible hypothesis (``outside``), so that when even the best description leaves more than
noise, every likelihood ratio is tempered by it (the quasi-likelihood correction, as in QAIC).

The families are approximations of the real mechanism: two of them can differ in χ² by hundreds
because of a systematic misfit in one stretch of one capture, which the noise alone would never
produce. The probabilities therefore account for where the evidence comes from, as pseudo-BMA+
does (Yao, Vehtari, Simpson & Gelman 2018, Bayesian Analysis 13(3) 917–1007): the data are cut
into units (``UNIT_BLOCKS`` consecutive blocks of one capture), the log likelihood of each
hypothesis is summed over the units with Bayesian-bootstrap weights (Dirichlet(1, …, 1), scaled
to the number of units), and the posterior is averaged over ``DRAWS`` draws. Evidence spread
over every unit stays decisive; evidence from a few units is tempered.

Priors (stated): none, outside_catalogue and each single family get equal prior weight; each
pair gets 1/F of it (F families), i.e. "two defects at once" is as likely a priori as one
particular defect.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .hypotheses import Fits

UNIT_BLOCKS = 32    # 4 ms at 8 kHz blocks: the exchangeable unit of the Bayesian bootstrap
DRAWS = 2000        # Monte-Carlo draws of the bootstrap (sampling precision ~1 %)


@dataclass
class Evidence:
    """Stage 3 result: per hypothesis name its BIC, prior and posterior probability."""

    bic: dict
    prior: dict
    probabilities: dict
    dispersion: float
    n: int

    def ranked(self):
        return sorted(self.probabilities.items(), key=lambda kv: -kv[1])


def evidence(fits: Fits, *, seed: int = 1) -> Evidence:
    n = fits.windows.n
    hyps = fits.hypotheses
    names = list(hyps)
    out = hyps["outside_catalogue"]
    p_state = sum(cw.J.shape[1] for cw in fits.windows.captures)
    dof = max(n - p_state - out.k, 1)
    phi = max(1.0, out.chi2 / dof)
    singles = [h for h in hyps.values() if len(h.effects) == 1 and not h.outside]
    F = max(len(singles), 1)
    prior = {name: (1.0 / F if len(h.effects) == 2 and not h.outside else 1.0) for name, h in hyps.items()}
    z = sum(prior.values())
    prior = {k: v / z for k, v in prior.items()}
    bic = {name: h.chi2 / phi + h.k * np.log(n) for name, h in hyps.items()}

    # per-unit log likelihood, hypotheses × units
    ll = []
    for name in names:
        row = []
        for e in hyps[name].residuals():
            for a in range(0, e.size, UNIT_BLOCKS):
                row.append(-0.5 * float(np.sum(e[a:a + UNIT_BLOCKS] ** 2)) / phi)
        ll.append(row)
    ll = np.array(ll)
    U = ll.shape[1]
    const = np.array([-0.5 * hyps[k].k * np.log(n) + np.log(prior[k]) for k in names])
    rng = np.random.default_rng(seed)
    alpha = rng.dirichlet(np.ones(U), size=DRAWS) * U          # DRAWS × U, each row sums to U
    zz = alpha @ ll.T + const                                   # DRAWS × H
    zz -= zz.max(axis=1, keepdims=True)
    w = np.exp(zz)
    post = (w / w.sum(axis=1, keepdims=True)).mean(axis=0)
    return Evidence({k: float(v) for k, v in bic.items()}, prior,
                    {k: float(p) for k, p in zip(names, post)}, float(phi), int(n))
