"""Piecewise integration with terminal events, and the result object both operations return.

Force laws switch where elements engage (the buffer bites, the cam reaches its dwell), so the
integration stops at each switch and restarts from the exact crossing. Radau (implicit, order 5)
is used because the regularised Coulomb laws and a stiff pull rod make the system stiff.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

RTOL = 1e-7
ATOL = 1e-9


@dataclass
class Segment:
    t0: float
    t1: float
    sol: object          # scipy OdeSolution, or None for a frozen state
    state: np.ndarray    # the state at t0 (used when sol is None)
    mode: str


@dataclass
class Motion:
    """One simulated operation.

    Attributes
    ----------
    operation : "open" or "close"
    segments : list of Segment
        Piecewise solution; ``mode`` says which state layout each one has.
    events : dict
        Named instants [s since motion start]: ``buffer`` (opening), ``latched`` (closing),
        ``touch`` (closing contact touch) when they happen.
    observe : callable
        ``observe(segment, t) -> dict of arrays`` (travel, energies...) for times in a segment.
    """

    operation: str
    segments: list
    events: dict
    observe: object
    t_end: float
    info: dict = field(default_factory=dict)

    def sample(self, t) -> dict:
        """Observables at times ``t`` [s since motion start]; times before 0 give the rest state."""
        t = np.asarray(t, dtype=float)
        out = None
        for k, seg in enumerate(self.segments):
            last = k == len(self.segments) - 1
            sel = (t >= seg.t0) & ((t < seg.t1) | last)
            if k == 0:
                sel |= t < seg.t0
            if not np.any(sel):
                continue
            tt = np.clip(t[sel], seg.t0, seg.t1)
            obs = self.observe(seg, tt)
            if out is None:
                out = {name: np.full(t.shape, np.nan) for name in obs}
            for name, values in obs.items():
                out[name][sel] = values
        return out


def integrate(rhs, x0, t0, t_end, events, mode, *, max_step=np.inf):
    """Integrate ``rhs`` from t0 until t_end or the first terminal event.

    Returns (Segment, event_name or None, state at the end).
    """
    evs = list(events.values())
    names = list(events.keys())
    for ev in evs:
        ev.terminal = True
    res = solve_ivp(rhs, (t0, t_end), x0, method="Radau", rtol=RTOL, atol=ATOL, dense_output=True,
                    events=evs or None, max_step=max_step)
    if res.status < 0:
        raise RuntimeError(f"the {mode} integration failed: {res.message}")
    hit = None
    if evs and res.status == 1:
        for name, te in zip(names, res.t_events):
            if te.size:
                hit = name
    return Segment(t0, float(res.t[-1]), res.sol, np.asarray(x0, float), mode), hit, res.y[:, -1].copy()
