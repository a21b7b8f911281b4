"""Warm starts: where monitoring already knows the answer to within a few per cent.

Each breaker has its previous good fit and its breaker file's design values. The warm search
runs CMA-ES in a box around that prior, with a σ0 matched to the prior's spread, stops once the
RMSE sits at the noise floor, and leaves the last digits to the least-squares polish.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics.breaker import CLOSING_PARAMETERS, OPENING_PARAMETERS, Breaker
from .model_bias import ResidualShape
from .parameter_space import ParameterSpace

# Relative spread (1 σ) of a prior: a previous fit moves by a few per cent between operations;
# design values are only as good as the breaker file's tolerances.
SPREAD_PREVIOUS_FIT = 0.05
SPREAD_DESIGN = 0.15
BOX_SIGMAS = 3.0   # the warm box spans ±3 σ of the prior


@dataclass(frozen=True)
class Prior:
    """A starting point for one operation's fit.

    Attributes
    ----------
    operation : {"open", "close"}
    parameters : dict
        AO, BO, DO, EO [s^-2, s^-2, s^-1, s^-2] or AC, BC, CC [s^-2, -, s^-2].
    onset_delay_s : float or None
        Onset delay of the previous fit [s]; None when unknown (design values).
    spread : float
        Relative 1-σ uncertainty of the parameters.
    rmse_ratio : float or None
        The previous fit's RMSE over its noise floor (how well the model explained that curve).
    source : str
        Where it came from, in words (shown in the result).
    residual_shape : ResidualShape or None
        The breaker's recent operations' mean residual (the previous fit's), which the interval
        leaves out as the model's bias (service.estimation.model_bias).
    """

    operation: str
    parameters: dict
    onset_delay_s: float | None
    spread: float
    rmse_ratio: float | None
    source: str
    residual_shape: ResidualShape | None = None

    def names(self) -> tuple:
        return OPENING_PARAMETERS if self.operation == "open" else CLOSING_PARAMETERS

    def usable(self) -> bool:
        values = [self.parameters.get(n) for n in self.names()]
        return all(isinstance(v, (int, float)) and np.isfinite(v) and v > 0 for v in values)


def prior_from_design(breaker: Breaker, operation: str) -> Prior:
    """The breaker file's design values (Eqs. 8 and 12) as a prior."""
    design = breaker.design_parameters()
    names = OPENING_PARAMETERS if operation == "open" else CLOSING_PARAMETERS
    return Prior(operation, {n: float(design[n]) for n in names}, None, SPREAD_DESIGN, None,
                 "breaker file design values")


def prior_from_fit(result: dict, source: str) -> Prior | None:
    """A previous fit's stored result dict as a prior; None when it cannot serve as one."""
    try:
        operation = result["operation"]
        names = OPENING_PARAMETERS if operation == "open" else CLOSING_PARAMETERS
        params = {n: float(result["parameters"][n]) for n in names}
        tau = result.get("onset_delay_s")
        rmse, noise = result.get("rmse_rad"), result.get("noise_rad")
        ratio = float(rmse) / float(noise) if rmse and noise else None
    except (KeyError, TypeError, ValueError):
        return None
    shape = ResidualShape.from_dict(result.get("residual_shape") or {})
    prior = Prior(operation, params, float(tau) if tau is not None else None, SPREAD_PREVIOUS_FIT,
                  ratio, source, shape if shape is not None and shape.operation == operation else None)
    return prior if prior.usable() else None


def warm_space(prior: Prior, names: tuple, tau_max: float) -> tuple[ParameterSpace, np.ndarray]:
    """The box CMA-ES searches around ``prior`` and the prior's position in its unit cube.

    Every model parameter spans ±``BOX_SIGMAS`` σ of the prior (kept positive); the onset delay
    spans its whole admissible range [0, tau_max] because it depends on the trigger, not on
    the mechanism.
    """
    ranges, x0 = {}, []
    for n in names:
        if n == "tau":
            tau = prior.onset_delay_s if prior.onset_delay_s is not None else 0.25 * tau_max
            ranges[n] = (0.0, tau_max)
            x0.append(min(max(tau / tau_max, 0.02), 0.98))
            continue
        v = prior.parameters[n]
        half = BOX_SIGMAS * prior.spread * v
        ranges[n] = (max(v - half, 1e-3 * v), v + half)
        x0.append((v - ranges[n][0]) / (ranges[n][1] - ranges[n][0]))
    return ParameterSpace.from_ranges(names, ranges), np.array(x0)


def sigma0(prior: Prior) -> float:
    """CMA-ES σ0 in the warm box's unit cube: one prior σ (the box is 2·BOX_SIGMAS σ wide)."""
    return 1.0 / (2.0 * BOX_SIGMAS)
