"""Stage 1 helpers: a capture's valid window as the diagnosis sees it (block-averaged samples,
the noise floor) and the model curve (the catalogue's compiled integrator, any set of effects)
at those samples."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics.breaker import Breaker
from ..mechanics.coordinates import operation_coordinate
from ..mechanics.effects import simulate_effects

# A block is a time, not a sample count, so that a 5 kS/s analyser record is diagnosed like a
# 128 kHz capture: 125 µs (16 samples at 128 kHz; one sample at 8 kS/s and below). It is well
# under the ~1 ms the shortest effect (a latch ramp, a contact touch) lasts, so averaging within a
# block loses nothing the catalogue or the discrepancy term resolves.
BLOCK_S = 1.0 / 8_000    # [s]
JAC_STEP = 1e-4     # relative finite-difference step of the state Jacobian

# A capture's own state: the reduced parameters it estimates plus, for an opening, CO [s^-1], the
# linear damping that grease and puffer gas change with the temperature from one operation to the
# next (issue 29: held at the breaker file's value it leaves a 0.18σ gap at ±10 %, exactly a
# catalogued viscous friction), and α0 [rad], the buffer engagement angle (±3 % leaves 0.20σ; it
# is profiled in every hypothesis, so that a buffer effect is not fitted against an α0 the
# reduced model bent towards it). The reduced closing (Eq. 7) has no velocity term, so no
# counterpart: healthy closings of A, B and C already sit at the noise floor
# (bench/healthy_floor.py). The onset delay τ [s] follows in the state vector x.
STATE = {"open": ("AO", "BO", "DO", "EO", "CO", "alpha0"), "close": ("AC", "BC", "CC")}
ALPHA0_SPAN = 0.15   # ±15 % about the breaker file's α0 [rad]: a unit's buffer setting, 5× the ±3 % tolerance


@dataclass
class WindowData:
    """Block means of the operation coordinate over the valid window.

    t : block centres [s from the window start (latch shock)]; y : block means [rad];
    count : samples per block (BLOCK_S of them); noise : per-sample noise sd [rad]; t_start : window start in
    capture time [s]; dc : DC used for closings [s^-2]; source : capture name.
    """

    t: np.ndarray
    y: np.ndarray
    count: np.ndarray
    noise: float
    t_start: float
    dc: float
    source: str

    @property
    def weight(self) -> np.ndarray:
        """Per block 1/sd of the block mean [1/rad]: √count/σ."""
        return np.sqrt(self.count) / self.noise


def design_state(breaker: Breaker, operation: str) -> np.ndarray:
    """The breaker's design values of STATE[operation] (α0 the breaker's)."""
    design = {**breaker.design_parameters(), "alpha0": float(breaker.alpha0)}
    return np.array([float(design[k]) for k in STATE[operation]])


def state_bounds(x, operation: str, tau: tuple[float, float]):
    """Bounds of a state vector x (STATE then τ): ×0.2…×5 of each value, α0 ±ALPHA0_SPAN, τ in
    ``tau`` [s]."""
    x = np.asarray(x, float)
    lo, hi = np.minimum(x * 0.2, x * 5.0), np.maximum(x * 0.2, x * 5.0)
    if "alpha0" in STATE[operation]:
        i = STATE[operation].index("alpha0")
        lo[i], hi[i] = x[i] * (1 - ALPHA0_SPAN), x[i] * (1 + ALPHA0_SPAN)
    lo[-1], hi[-1] = tau
    return lo, hi


def block_samples(sample_rate: float) -> int:
    """Samples per block at ``sample_rate`` [Hz]: BLOCK_S of them, at least one."""
    return max(1, int(round(float(sample_rate) * BLOCK_S)))


def window_data(capture, fit, breaker: Breaker, operation: str, valid=None) -> WindowData:
    """Cut the fit's valid window out of ``capture`` and block-average it. ``valid``: the mask
    of the samples that are numbers (``windows.valid_samples``); a block holding any other is
    left out, so the evidence rests on recorded samples only."""
    y_all = operation_coordinate(capture.travel, operation, breaker.stroke)
    t_all = capture.t
    sel = (t_all >= fit.window_s[0]) & (t_all <= fit.window_s[1])
    t, y = t_all[sel] - fit.window_s[0], y_all[sel]
    edges = np.arange(0, t.size, block_samples(capture.sample_rate))
    count = np.diff(np.append(edges, t.size)).astype(float)
    tb = np.add.reduceat(t, edges) / count
    yb = np.add.reduceat(y, edges) / count
    if valid is not None:
        bad = np.add.reduceat((~np.asarray(valid, bool)[sel]).astype(float), edges) > 0
        tb, yb, count = tb[~bad], yb[~bad], count[~bad]
    dc = float(getattr(fit, "dc_used", None) or breaker.design_parameters()["DC"])
    return WindowData(tb, yb, count, float(fit.noise_rad), float(fit.window_s[0]), dc,
                      capture.source or "capture")


# The coarser RK4 step: one step per block [s], 2.4x less work than the curves' 1/16000 s. The
# reduced opening and the smooth families (SMOOTH_OPENING) are integrated on it, curves and
# Jacobian columns alike: their curves move by ≤ 1e-9 rad and their state columns by less than
# the finite difference's own error (tests/diagnosis/test_jacobian_step.py).
JAC_DT_S = BLOCK_S
CURVE_DT_S = 1.0 / 16_000   # the curves' RK4 step [s] (``simulate_effects``' default)
# Openings whose every effect is one of these are integrated on the Jacobians' grid too: their
# curves at one step per block differ from those at CURVE_DT_S by ≤ 1e-9 rad over every start
# of theirs from its own strength to the fits' bounds (the reduced model 3e-11), 20 times under
# the 1.9e-8 rad that would move χ² by 0.01 on 10⁴ blocks of a 1.5 mrad sensor (2√n·δ/σ_block;
# tests/diagnosis/test_jacobian_step.py checks the bound). The linkage, the buffer, the rod, the
# Stribeck friction and the spring stiffening change their curves by 6e-8 to 2e-4 rad there, and
# every closing by ~2e-5 rad (the cam): they keep the finer step.
SMOOTH_OPENING = frozenset({"puffer_gas", "viscous_friction", "sensor_nonlinearity"})


def curve_step(operation: str, effects=()) -> float:
    """The RK4 step [s] of a model curve of ``operation`` under ``effects`` (see SMOOTH_OPENING)."""
    if operation == "open" and all(e[0] in SMOOTH_OPENING for e in effects):
        return JAC_DT_S
    return CURVE_DT_S


def model_curve(x, data: WindowData, breaker: Breaker, operation: str, effects=(), t=None,
                sensor_side: bool = False, dt_max: float | None = None):
    """Operation coordinate [rad] of the prototype at block centres (or ``t`` [s from the
    window start]); ``x`` = state parameters followed by the onset delay τ [s]; ``dt_max`` the
    RK4 step [s] (default ``curve_step``; ``JAC_DT_S`` for a Jacobian's columns)."""
    names = STATE[operation]
    params = dict(zip(names, x[: len(names)]))
    co = params.pop("CO", 0.0)
    a0 = params.pop("alpha0", None)
    tau = x[len(names)]
    tt = (data.t if t is None else t) - tau
    if operation == "close":
        params["DC"] = data.dc
        rest = float(breaker.cam.theta2[0])
    else:
        rest = 0.0
    if dt_max is None:
        dt_max = curve_step(operation, effects)
    theta, _ = simulate_effects(operation, params, np.maximum(tt, 0.0), breaker, effects, dt_max=dt_max,
                                sensor_side=sensor_side, CO=co if co > 0 else None, alpha0=a0)
    return np.where(tt < 0, rest, theta)


def gap_rms(d, count, noise):
    """Model misfit RMS per sample [rad] from block-mean residuals ``d`` [rad] (noise removed)."""
    if d.size == 0:
        return 0.0
    return float(np.sqrt(max(np.mean(d * d - noise * noise / count), 0.0)))


def state_columns(x, data: WindowData, breaker: Breaker, operation: str, effects=(), steps=None) -> np.ndarray:
    """Whitened finite-difference columns ∂model/∂x_j · w of the state ``x`` (STATE then τ) under
    ``effects``, on the curve's grid (``curve_step``: the Jacobians' coarser one for the reduced
    model and the smooth families; a family with a kink of its own, such as the buffer's free
    travel, keeps the finer one, since α0 and τ move that kink within a step and the coarse
    grid's error with it: measured, a Gauss–Newton refit of a buffer then stalled at χ² 2289
    where the finer columns reach 1857); ``steps`` [x's units] default ``JAC_STEP``·|x_j| (τ:
    2 µs). Non-finite entries are 0."""
    w = data.weight
    dt = curve_step(operation, effects)
    m0 = model_curve(x, data, breaker, operation, effects, dt_max=dt)
    cols = []
    for j in range(x.size):
        h = (2e-6 if j == x.size - 1 else JAC_STEP * max(abs(x[j]), 1e-6)) if steps is None else steps[j]
        xp = np.array(x, float)
        xp[j] += h
        cols.append((model_curve(xp, data, breaker, operation, effects, dt_max=dt) - m0) * w / h)
    J = np.column_stack(cols)
    return np.where(np.isfinite(J), J, 0.0)


def fd_steps(z, rel: float, lo, hi) -> np.ndarray:
    """The forward-difference steps scipy's ``least_squares`` takes for ``diff_step=rel``
    (``rel``·sign·max(1, |z|), turned back where it would leave the bounds): the Jacobians the
    fits supply on the coarser grid step like the ones scipy computed."""
    z = np.asarray(z, float)
    sign = np.where(z >= 0, 1.0, -1.0)
    h = rel * sign * np.maximum(1.0, np.abs(z))
    h = (z + h) - z
    lo, hi = np.broadcast_to(lo, z.shape), np.broadcast_to(hi, z.shape)
    out = (z + h < lo) | (z + h > hi)
    fits = np.abs(h) <= np.maximum(z - lo, hi - z)
    return np.where(out & fits, -h, h)
