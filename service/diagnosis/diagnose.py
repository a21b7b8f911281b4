"""``diagnose``: the gap diagnosis of one breaker from N captures of one operation.

A one-way pipeline, one module per stage:

1. ``windows``    the captures' data: valid windows, noise, reduced fit, state Jacobian;
2. ``predictive`` the evidence, the capture as its unit: each hypothesis (none, each family's
                  subspace, pairs, a shared discrepancy) scored by leave-one-capture-out predictive
                  density, combined by pseudo-BMA+;
3. ``hypotheses`` the nonlinear refit of the leading hypotheses only, to report how far the gap
                  shrinks (``evidence``: the noise model's figures beside the weights);
4. ``decision``   the one rule: state what reaches P_NAME (calibrated), else ambiguous;
5. ``report``     the JSON-ready result (+ ``measurement``: the recording that would decide).
"""

from __future__ import annotations

import time

import numpy as np

from ..mechanics.breaker import Breaker
from ..mechanics.effects import EFFECT_NAMES
from .decision import decide
from .errors import DiagnosisError
from .evidence import evidence
from .hypotheses import catalogue_for, fit_reported
from .linearised import holdout_shrink
from .predictive import score
from .measurement import next_measurement
from .report import build
from .windows import prepare

__all__ = ["diagnose", "DiagnosisError"]


def diagnose(captures, breaker: Breaker, operation: str, *, effects=None, seed: int = 1,
             fitter=None, next_measurements: bool = True, strengths: dict | None = None) -> dict:
    """Diagnose the sim-to-real gap of one breaker from its captures of one operation.

    Parameters
    ----------
    captures : sequence of Capture (one breaker; conditions may differ between them)
    breaker : Breaker
    operation : {"open", "close"}
    effects : sequence of str, optional
        The catalogue to try (default: every effect acting on ``operation``).
    seed : int
        Seed of the reduced-model fit.
    fitter : callable, optional
        ``fitter(capture, breaker, operation, seed=...) -> FitResult`` (default
        ``service.estimation.fit_capture``).
    next_measurements : bool
        Compute ``next_measurement`` when rivals remain.
    strengths : dict, optional
        The breaker's typical effect strengths (its breaker file's ``[effects]``; default the
        catalogue's REFERENCE_STRENGTHS): the scale of the fits and of the ``absorbed`` check.

    Returns
    -------
    dict : the result contract (docs/diagnosis.md).
    """
    t0 = time.perf_counter()
    if operation not in ("open", "close"):
        raise DiagnosisError(f"operation must be 'open' or 'close', got {operation!r}")
    unknown = [n for n in (effects or []) if n not in EFFECT_NAMES]
    if unknown:
        raise DiagnosisError(f"unknown effect(s) {', '.join(unknown)}; known: {', '.join(EFFECT_NAMES)}")
    catalogue = catalogue_for(operation, effects)
    if not catalogue:
        raise DiagnosisError(f"none of the given effects acts on an {operation} operation")
    windows = prepare(list(captures), breaker, operation, fitter=fitter, seed=seed)
    try:
        return _diagnose(windows, catalogue, strengths, next_measurements, t0, time.perf_counter() - t0)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError):
        # a numerical failure is the records' (non-finite model values, a fit that did not
        # converge): said in words naming them, never the library's message
        names = ", ".join(c.data.source for c in windows.captures)
        raise DiagnosisError(f"{names}: the joint fit of the hypotheses did not converge on these records "
                             f"(a model value or a residual is not a number): refused, no diagnosis") from None


def _diagnose(windows, catalogue, strengths, next_measurements, t0, t_prepare):
    t1 = time.perf_counter()
    scores = score(windows, catalogue)
    t2 = time.perf_counter()
    fits = fit_reported(windows, scores, rivals=2 if next_measurements else 1)
    t3 = time.perf_counter()
    ev = evidence(fits, scores)
    dec = decide(fits, ev, catalogue, strengths)
    nm = next_measurement(fits, dec.rivals) if (next_measurements and dec.status == "ambiguous") else []
    ho = holdout_shrink(windows, fits.hypotheses[dec.hypothesis]) if dec.status == "named" else None
    result = build(fits, ev, dec, nm, ho, time.perf_counter() - t0, scores)
    result["stages_s"] = {"prepare": t_prepare, "evidence": t2 - t1, "report_refit": t3 - t2,
                          "rest": time.perf_counter() - t3}
    return result
