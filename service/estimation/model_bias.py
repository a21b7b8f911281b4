"""The fit's residual split into the part that repeats from operation to operation and the rest.

A reduced model that misses a mild physical effect (an orifice buffer's speed law, a lever's bow)
leaves the same residual shape in every operation of one breaker. That shape is a **bias** of the
fit: it moves every estimate alike, so it does not widen the spread of the estimates, and an
interval that counts it as noise (the AR sandwich of the whole residual) is several times too
wide. What varies from operation to operation (the sensor's noise, torsional modes struck with a
new amplitude each time, the zero's drift) is what the interval must stand for.

The interval comes from the residual less its smooth part (``varying_part``): the misfit of a
mild effect is smooth over the stroke, what the sensor adds anew is rough. The repeating part is
reported as the fit's model bias (``bias_summary``): the breaker's recent operations' mean residual,
aligned on the start of motion, where there is one (``ResidualShape``, carried from fit to fit on
the warm start), else this capture's smooth part.

bench/interval_repeat.py compares, on repeated openings of prototypes A–C (clean, and with mild
effects through a realistic sensor), the AR sandwich of the whole residual (the earlier estimator),
the idle noise alone, the residual less the breaker's mean residual, and the residual less its
smooth part; the last measured best (docs/estimation.md). Kennedy & O'Hagan (J. R. Stat. Soc. B 63
(2001) 425–464) name the repeating part the model discrepancy; estimating it from repeated
experiments on one system is their "replicate observations" case.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Operations the shape averages over: a running mean until then, an exponential one after, so an
# effect that changes slowly (a leak) is followed within about this many operations.
SHAPE_MEMORY = 20
# Operations needed before the shape stands for the repeat: a mean of k residuals still carries
# 1/k of one operation's own variation (a third at k = 3).
SHAPE_MIN_OPS = 3
# Without a history, the smooth part of one capture's residual stands in for the repeat: Legendre
# polynomials up to this degree over the valid interval, i.e. misfits whose time scale is
# longer than about a ninth of the stroke (~6 ms of a 55 ms opening). A mild unmodelled effect acts
# on that scale (a buffer's speed law over its ~20 ms, friction over the whole stroke); the
# torsional modes a strike rings (300–1500 Hz) are far shorter. bench/interval_repeat.py measures it.
SMOOTH_DEGREE = 8


@dataclass(frozen=True)
class ResidualShape:
    """The mean residual of a breaker's recent operations of one kind.

    operation : "open" | "close"
    t0_s : time of the first value after the start of motion [s]
    dt_s : spacing of the values [s]
    values_rad : mean residual (measured − model) [rad], one per block
    count : operations averaged (capped at SHAPE_MEMORY: the weight of the newest is 1/count)
    """

    operation: str
    t0_s: float
    dt_s: float
    values_rad: tuple
    count: int

    def at(self, t_rel: np.ndarray) -> np.ndarray:
        """The shape at times ``t_rel`` after the start of motion [s]; 0 outside its span [rad]."""
        v = np.asarray(self.values_rad, dtype=float)
        tt = self.t0_s + self.dt_s * np.arange(v.size)
        return np.interp(np.asarray(t_rel, dtype=float), tt, v, left=0.0, right=0.0)

    def to_dict(self) -> dict:
        return {"operation": self.operation, "t0_s": float(self.t0_s), "dt_s": float(self.dt_s),
                "values_rad": [round(float(v), 9) for v in self.values_rad], "count": int(self.count)}

    @classmethod
    def from_dict(cls, d) -> ResidualShape | None:
        """The stored form back; None when it is missing or not a shape (an older fit's result)."""
        try:
            values = tuple(float(v) for v in d["values_rad"])
            shape = cls(str(d["operation"]), float(d["t0_s"]), float(d["dt_s"]), values, int(d["count"]))
        except (KeyError, TypeError, ValueError):
            return None
        ok = shape.dt_s > 0 and shape.count >= 1 and len(values) >= 2 and np.all(np.isfinite(values))
        return shape if ok else None


def updated(shape: ResidualShape | None, operation: str, t_rel: np.ndarray,
            residual_rad: np.ndarray) -> ResidualShape:
    """The shape with one more operation's residual (on its block grid, ``t_rel`` after motion)."""
    t_rel = np.asarray(t_rel, dtype=float)
    r = np.asarray(residual_rad, dtype=float)
    if shape is None or shape.operation != operation:
        dt = float(np.median(np.diff(t_rel))) if t_rel.size > 1 else 1e-4
        return ResidualShape(operation, float(t_rel[0]), dt, tuple(r.tolist()), 1)
    tt = shape.t0_s + shape.dt_s * np.arange(len(shape.values_rad))
    new = np.interp(tt, t_rel, r, left=np.nan, right=np.nan)
    old = np.asarray(shape.values_rad, dtype=float)
    count = min(shape.count + 1, SHAPE_MEMORY)
    mixed = np.where(np.isfinite(new), old + (np.nan_to_num(new) - old) / count, old)
    return ResidualShape(operation, shape.t0_s, shape.dt_s, tuple(mixed.tolist()), count)


def varying_part(residual_rows: np.ndarray, weight: np.ndarray, t_rel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The weighted residual rows split into what varies between operations and what repeats.

    ``residual_rows`` are the fit's weighted residuals (block residual × ``weight``), ``t_rel``
    the blocks' times after the start of motion [s]. The repeating part is the rows' weighted
    least-squares projection on Legendre polynomials up to ``SMOOTH_DEGREE`` over the valid
    interval: a reduced model's stated simplifications (a speed law, a lever's bow, friction)
    misfit smoothly over the whole stroke, the same way every time, while what the sensor adds
    anew (noise, ringing struck at the latch and the impact) is rough. Returns (varying,
    repeating), both weighted rows; a window too short for the basis keeps everything as varying.
    """
    t_rel = np.asarray(t_rel, dtype=float)
    rows = np.asarray(residual_rows, dtype=float)
    if t_rel.size <= 4 * (SMOOTH_DEGREE + 1):
        return rows, np.zeros_like(rows)
    u = 2.0 * (t_rel - t_rel[0]) / max(t_rel[-1] - t_rel[0], 1e-12) - 1.0
    B = np.polynomial.legendre.legvander(u, SMOOTH_DEGREE) * np.asarray(weight, dtype=float)[:, None]
    coef, *_ = np.linalg.lstsq(B, rows, rcond=None)
    smooth = B @ coef
    return rows - smooth, smooth


def repeating_rows(shape: ResidualShape | None, smooth_rows: np.ndarray, weight: np.ndarray,
                   t_rel: np.ndarray) -> tuple[np.ndarray, str]:
    """The residual the breaker repeats, as weighted rows, and where it comes from in words: its
    recent operations' mean residual when there are ``SHAPE_MIN_OPS`` of them, else this
    capture's own smooth part (``varying_part``)."""
    if shape is not None and shape.count >= SHAPE_MIN_OPS:
        return np.asarray(weight) * shape.at(t_rel), f"mean residual of the breaker's last {shape.count} operations"
    return np.asarray(smooth_rows), "the smooth part of this operation's residual: no history of the breaker yet"


def bias_summary(rows: np.ndarray, basis: str, weight: np.ndarray, jacobian: np.ndarray,
                 noise_rad: float, names: list) -> dict:
    """The model bias in the fit's own terms, from the repeating residual ``rows`` (weighted).

    ``rms_rad``: the repeating residual's rms over the valid interval [rad], and over the idle
    noise. ``effect_bound``: for each parameter, the largest shift a misfit of that size could
    cause if it lay along the parameter's own direction, |δ|·sqrt((JᵀJ)⁻¹ᵢᵢ) (Cauchy–Schwarz)
    [parameter unit]: an upper bound, since the reduced model has already taken up the part of
    the misfit it can express (the residual is orthogonal to J at the estimate), which no
    residual can show.
    """
    rows = np.asarray(rows, dtype=float)
    norm = float(np.sqrt(np.sum(rows * rows)))
    n = max(float(np.sum(np.asarray(weight) ** 2)), 1.0)
    J = np.asarray(jacobian, dtype=float)
    d = np.sqrt(np.sum(J * J, axis=0))
    d = np.where(d > 0, d, 1.0)
    try:
        inv = np.linalg.inv((J.T @ J) / np.outer(d, d)) / np.outer(d, d)
    except np.linalg.LinAlgError:
        inv = np.linalg.pinv((J.T @ J) / np.outer(d, d)) / np.outer(d, d)
    bound = norm * np.sqrt(np.clip(np.diag(inv), 0.0, None))
    rms = norm / np.sqrt(n)
    return {"basis": basis, "rms_rad": rms, "rms_over_noise": rms / noise_rad if noise_rad > 0 else None,
            "effect_bound": {str(k): float(v) for k, v in zip(names, bound)}}
