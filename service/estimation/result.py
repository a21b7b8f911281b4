"""The result of one fit, as the CLI, the service and the studies see it."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drivers.capture import Capture
from ..mechanics.breaker import Breaker
from .finite import finite_tree
from ..mechanics.coordinates import travel_from_coordinate


@dataclass
class FitResult:
    """Estimated model parameters of one operation with their uncertainty.

    Attributes
    ----------
    operation : str
        ``open`` or ``close``.
    parameters : dict
        Estimates: AO [s^-2], BO [s^-2], DO [s^-1], EO [s^-2] or AC [s^-2], BC [-], CC [s^-2].
    stderr, ci95 : dict
        Standard errors and 95 % confidence intervals, same units.
    correlation : list of list
        Correlation matrix of ``parameter_names`` (the onset delay included last).
    rmse_rad : float
        RMSE between fitted and measured curves over the valid interval, at the measured samples.
    fitness : float
        The paper's F = 1/RMSE [rad^-1].
    window_s : tuple
        Valid interval [start, end] in seconds from the first sample.
    onset_delay_s : float
        Estimated delay from the latch shock to the onset of motion [s].
    noise_rad : float
        Travel noise from the idle pre-trigger samples [rad].
    evaluations : int
        Model evaluations (CMA-ES candidates plus polish).
    runtime_s : float
    identifiable : bool
        False when the fit is ill-conditioned (parameters not separately determined).
    condition_number : float
    dc_used, dc_source :
        For closings, the opening-spring factor DC used [s^-2] and where it came from.
    ranges : dict
        Final search ranges (after re-adaptation).
    readaptations : int
        How many times a range had to be moved (paper steps 5–6).
    warnings : list of str
    characteristics : dict
        Classic travel characteristics of the measured curve.
    start : str
        How the search started: ``cold search`` or ``warm start from …``.
    structure : dict
        Structure of an unknown design estimated from the curve (``alpha0``: value, stderr,
        ci95 [rad]); its uncertainty is already in every parameter's CI.
    characteristics_record : dict
        The characteristics in the record's own unit (mm, m/s) for a travel recorded in mm.
    command_source : str
        What the window starts at: ``latch shock``, ``coil C4/...``, ``first sample``.
    picked : dict or None
        For a record of several operations: which one was fitted (kind, index, of how many).
    interval_noise : dict or None
        Which noise the intervals (and the operation page's residual band) stand for: ``basis``
        "idle samples" or "residual in motion", ``band_rad`` the band's 1σ [rad], the
        residual's AR order and each parameter's widening over the idle-noise interval
        (service.estimation.uncertainty).
    zero_rad : float
        The operation coordinate's level at rest before the motion, taken off before the fit
        (the transducer's zero in this operation) [rad]; the fitted curve is drawn on top of it.
    model_bias : dict or None
        The residual the breaker's recent operations repeat (service.estimation.model_bias): its
        rms [rad], over the noise, and each parameter's largest possible shift from it.
    residual_shape : ResidualShape or None
        The mean residual of the recent operations including this one: the next fit's warm
        start carries it.
    """

    operation: str
    parameters: dict
    stderr: dict
    ci95: dict
    correlation: list
    parameter_names: list
    rmse_rad: float
    fitness: float
    window_s: tuple
    onset_delay_s: float
    noise_rad: float
    evaluations: int
    runtime_s: float
    identifiable: bool
    condition_number: float
    dc_used: float | None = None
    dc_source: str | None = None
    ranges: dict = field(default_factory=dict)
    readaptations: int = 0
    stages: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    characteristics: dict = field(default_factory=dict)
    start: str = "cold search"
    structure: dict = field(default_factory=dict)
    characteristics_record: dict = field(default_factory=dict)
    command_source: str = "latch shock"
    picked: dict | None = None
    interval_noise: dict | None = None
    zero_rad: float = 0.0
    model_bias: dict | None = None
    residual_shape: object | None = None

    def to_dict(self) -> dict:
        out = {
            "operation": self.operation,
            "parameters": {k: float(v) for k, v in self.parameters.items()},
            "ci95": {k: [float(a), float(b)] for k, (a, b) in self.ci95.items()},
            "stderr": {k: float(v) for k, v in self.stderr.items()},
            "correlation": {"names": list(self.parameter_names),
                            "matrix": [[round(float(v), 6) for v in row] for row in self.correlation]},
            "rmse_rad": float(self.rmse_rad),
            "fitness": float(self.fitness),
            "window_s": [float(self.window_s[0]), float(self.window_s[1])],
            "onset_delay_s": float(self.onset_delay_s),
            "noise_rad": float(self.noise_rad),
            "evaluations": int(self.evaluations),
            "runtime_s": float(self.runtime_s),
            "identifiable": bool(self.identifiable),
            "condition_number": float(self.condition_number),
            "ranges": self.ranges,
            "readaptations": int(self.readaptations),
            "stages": self.stages,
            "warnings": list(self.warnings),
            "characteristics": self.characteristics,
            "start": self.start,
        }
        if self.structure:
            out["structure"] = self.structure
        if self.characteristics_record:
            out["characteristics_record"] = self.characteristics_record
        out["command_source"] = self.command_source
        if self.picked is not None:
            out["picked"] = self.picked
        if self.interval_noise is not None:
            out["interval_noise"] = self.interval_noise
        out["zero_rad"] = float(self.zero_rad)
        if self.model_bias is not None:
            out["model_bias"] = self.model_bias
        if self.residual_shape is not None:
            out["residual_shape"] = self.residual_shape.to_dict()
        if self.operation == "close":
            out["dc_used"] = float(self.dc_used)
            out["dc_source"] = self.dc_source
        return finite_tree(out)  # strict JSON: a NaN or ∞ is null with its reason (issue 57)

    def fitted_travel(self, capture: Capture, breaker: Breaker) -> np.ndarray:
        """The fitted model as travel [rad from closed] at every sample of ``capture``.

        Before the onset of motion the model is at rest; the curve is the model's, also beyond
        the valid interval.
        """
        return self.travel_at(capture.t, breaker)

    def travel_at(self, t, breaker: Breaker) -> np.ndarray:
        """The fitted model's travel [rad from closed] at times ``t`` [s from the capture's first sample]."""
        return fitted_travel(self.operation, self.parameters, self.window_s[0], self.onset_delay_s,
                             t, breaker, dc_used=self.dc_used,
                             alpha0=self.structure.get("alpha0", {}).get("value"),
                             co=self.structure.get("CO", {}).get("value"), zero_rad=self.zero_rad)


def fitted_travel(operation: str, parameters: dict, window_start_s: float, onset_delay_s: float,
                  t: np.ndarray, breaker: Breaker, *, dc_used: float | None = None,
                  alpha0: float | None = None, co: float | None = None, zero_rad: float = 0.0) -> np.ndarray:
    """The model curve of a stored fit, rebuilt from its parameters (nothing else is stored).

    Parameters
    ----------
    operation : {"open", "close"}
    parameters : dict
        AO, BO, DO, EO [s^-2, s^-1] or AC [s^-2], BC [-], CC [s^-2].
    window_start_s, onset_delay_s : float
        The fit's valid-interval start and onset delay [s].
    t : ndarray
        Times from the capture's first sample [s].
    breaker : Breaker
    dc_used : float, optional
        The closing's opening-spring factor DC [s^-2].
    alpha0, co : float, optional
        Buffer engagement [rad] and puffer damping CO [s^-1] an unknown design's fit estimated
        (``structure``); else the breaker file's.
    zero_rad : float
        The operation coordinate's rest level the fit took off (``FitResult.zero_rad``) [rad].

    Returns
    -------
    ndarray : travel [rad from closed] at ``t``.
    """
    from .curves import ClosingCurves, OpeningCurves

    t = np.asarray(t, dtype=float) - window_start_s
    if operation == "open":
        x = [parameters[k] for k in ("AO", "BO", "DO", "EO")] + [onset_delay_s]
        if alpha0 is not None or co is not None:
            import dataclasses

            breaker = dataclasses.replace(
                breaker, alpha0=float(breaker.alpha0 if alpha0 is None else alpha0),
                caec=breaker.caec if co is None else float(co) * breaker.J2 / breaker.raec**2)
        theta = OpeningCurves.at(t, x, breaker)
    else:
        x = [parameters[k] for k in ("AC", "BC", "CC")] + [onset_delay_s]
        theta = ClosingCurves.at(t, x, breaker, dc_used)
    return travel_from_coordinate(theta + zero_rad, operation, breaker.stroke)
