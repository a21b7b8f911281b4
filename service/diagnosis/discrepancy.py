"""Stage 2b — the discrepancy term: "something the catalogue does not describe".

Added to the best catalogued hypothesis, per capture, a cubic B-spline d(t) = B(t)·a with knots
every ``KNOT_S`` (0.5 ms: a transient of ~1 ms, a latch ramp or a sensor lag, is resolved) and at
the events of the fitted curve (latch release, buffer engagement α0, contact touch, the phase
edges of ``phases``). Its amplitude is marginalised under Zellner's g prior,
a ~ N(0, g·s²·G⁻¹), with g log-uniform on [1, n] (a discrete mixture of g priors, Liang et al.
2008, JASA 103:410; g = n is the unit-information prior whose Bayes factor is the BIC's).
Linear-Gaussian, so the Bayes factor against the catalogued hypothesis (a = 0) is closed form:

    ln BF(g) = −½ K ln(1 + g) + ½ g/(1 + g) · R/s²,   R = bᵀG⁺b,

with B the whitened basis with the capture's state projected out, G = BᵀB (rank K), b = Bᵀv, v
the catalogued hypothesis' whitened residual and s² the noise scale of ``evidence``. A residual
that is noise (R ≈ K s²) costs ≥ 0.1 nat per coefficient: a healthy group answers none. So that
a 1 ms transient is not diluted by a whole window of empty coefficients, the term is, per capture,
a mixture over where it lies: everywhere, or one ~4 ms stretch (``SEGMENT`` columns, every ~1 ms).
``unexplained``
is then this Bayes factor over the best catalogued hypothesis; where its posterior-mean fit lies
(phases, peak) is the ``discrepancy`` of the result.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import BSpline
from scipy.special import logsumexp

from .data import model_curve
from .phases import phase_bounds

KNOT_S = 0.5e-3                     # [s] knot spacing (a 1 ms transient spans two knots)
G_POINTS = 13                       # grid of the g prior's scale, log-uniform on [1, n]
SEGMENT = 8                         # columns of a local discrepancy: ~4 ms, a transient's support
STRIDE = 2                          # its positions every 2 columns (~1 ms)


def knots_of(cw, breaker, operation) -> np.ndarray:
    """Interior knots [s, window time] of capture ``cw``: every KNOT_S (at least 4 blocks apart)
    plus the events of its fitted reduced curve."""
    t = cw.data.t
    a, b = float(t[0]), float(t[-1])
    step = max(KNOT_S, 4.0 * float(np.median(np.diff(t))) if t.size > 1 else KNOT_S)
    grid = np.arange(a, b, step)[1:]
    tau = float(cw.x[-1])
    theta = model_curve(cw.x, cw.data, breaker, operation)
    events = [tau + e for _, e, _ in phase_bounds(operation, t - tau, theta, float(t[-1] - tau), breaker)]
    k = np.unique(np.concatenate([grid, [e for e in events if a < e < b]]))
    keep = np.concatenate([[True], np.diff(k) > 0.25 * step])       # no two knots closer than a quarter step
    return k[keep]


def basis(t: np.ndarray, interior: np.ndarray) -> np.ndarray:
    """Cubic B-splines on [t0, t1] with ``interior`` knots, evaluated at ``t`` (n × K)."""
    a, b = float(t[0]), float(t[-1])
    knots = np.concatenate([[a] * 4, interior, [b] * 4])
    return BSpline.design_matrix(np.clip(t, a, b), knots, 3).toarray()


@dataclass
class Discrepancy:
    """Per capture: projected whitened basis B, G = BᵀB, b = Bᵀv, the residual v, the knots."""

    B: list
    G: list
    b: list
    v: list
    knots: list
    noise: list = field(default_factory=list)   # per capture σ_i [rad]

    @property
    def k(self) -> int:
        return int(sum(g.shape[0] for g in self.G))

    def ls_residuals(self):
        """Residuals of the least-squares fit with every coefficient free (for the noise scale),
        from the pseudo-inverse of G = BᵀB (the "everywhere" component; computed once)."""
        if getattr(self, "_ls", None) is None:
            self._ls = [v - B @ self._components(i)[0][3] for i, (B, v) in enumerate(zip(self.B, self.v))]
        return self._ls

    def _components(self, i: int):
        """Capture i's alternatives for where the discrepancy lies: everywhere (all columns) or in
        one stretch of SEGMENT consecutive columns (every STRIDE): [(columns, K, R, coef)]
        (computed once per capture)."""
        cache = self.__dict__.setdefault("_comp", {})
        if i in cache:
            return cache[i]
        G, b = self.G[i], self.b[i]
        K = G.shape[0]
        spans = [np.arange(K)] + [np.arange(a, min(a + SEGMENT, K)) for a in range(0, max(K - SEGMENT, 0) + 1, STRIDE)]
        out = []
        for cols in spans:
            Gs, bs = G[np.ix_(cols, cols)], b[cols]
            w, V = np.linalg.eigh(Gs)
            keep = w > w.max() * 1e-10 if w.size and w.max() > 0 else np.zeros(w.size, bool)
            c = V[:, keep] @ ((V[:, keep].T @ bs) / w[keep])
            out.append((cols, int(keep.sum()), float(bs @ c), c))
        cache[i] = out
        return out

    @staticmethod
    def _lbf(K: int, R: float, n: int):
        """ln BF of one component on the g grid (R already divided by s²)."""
        gs = np.logspace(0.0, np.log10(max(n, 2)), G_POINTS)
        lb = np.array([-0.5 * K * np.log1p(g) + 0.5 * g / (1.0 + g) * R for g in gs])
        return float(logsumexp(lb) - np.log(len(gs))), float(gs[int(np.argmax(lb))])

    def log_bf(self, s2: float) -> float:
        """ln of the Bayes factor of "catalogued + discrepancy" over "catalogued": per capture the
        g prior marginalised and "where" (everywhere, or one stretch, equally likely a priori,
        half the prior on "everywhere")."""
        tot = 0.0
        for i, v in enumerate(self.v):
            comps = self._components(i)
            lb = np.array([self._lbf(K, R / s2, v.size)[0] for _, K, R, _ in comps])
            w = np.full(lb.size, 0.5 / max(lb.size - 1, 1))
            w[0] = 0.5 if lb.size > 1 else 1.0
            tot += float(logsumexp(lb, b=w))
        return tot

    def posterior_fit(self, s2: float):
        """Per capture the posterior-mean discrepancy (whitened) of its most probable component
        at its most probable g."""
        out = []
        for i, (B, v) in enumerate(zip(self.B, self.v)):
            best = None
            for cols, K, R, c in self._components(i):
                lb, g = self._lbf(K, R / s2, v.size)
                if best is None or lb > best[0]:
                    best = (lb, g, cols, c)
            _, g, cols, c = best
            out.append(g / (1.0 + g) * (B[:, cols] @ c))
        return out


def build(hyp, breaker, operation) -> Discrepancy:
    """The discrepancy term on top of hypothesis ``hyp`` (its residuals, its captures' states)."""
    Bs, Gs, bs, vs, ks, ns = [], [], [], [], [], []
    for cw, v in zip(hyp.captures, hyp.residuals()):
        k = knots_of(cw, breaker, operation)
        B = basis(cw.data.t, k) * cw.data.weight[:, None]
        B = B - cw.Q @ (cw.Q.T @ B)
        Bs.append(B)
        Gs.append(B.T @ B)
        bs.append(B.T @ v)
        vs.append(v)
        ks.append(k)
        ns.append(cw.data.noise)
    return Discrepancy(Bs, Gs, bs, vs, ks, ns)
