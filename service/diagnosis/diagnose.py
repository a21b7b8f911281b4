"""``diagnose``: the gap diagnosis of one breaker from N captures of one operation.

A one-way pipeline, one module per stage, each taking the last one's result:

1. ``windows``     prepare: the captures' valid windows, noise, reduced fit, state Jacobian;
2. ``predictive``  the evidence, the capture as its unit: each hypothesis (none, each family's
   + ``features`` subspace, every pair, a shared discrepancy) scored by leave-one-capture-out
                   predictive density, and every hypothesis's features from it;
3. ``scorer``      the learnt scorer: every hypothesis's probability from its features;
4. ``answer_set``  the 90 % set (conformal) and the name (Learn then Test); ``none`` itself is
                   decided before the scorer by ``none_test`` (the reduced model's residual
                   against the noise, a nested F test at a designed false rate);
5. ``linearised``  the nonlinear refit of the set's members only, to report how far the gap
                   shrinks with each (``evidence``: the noise model's figures);
6. ``decision``    the status from the set; ``report``: the JSON-ready result (+ ``measurement``:
                   the recording that would decide).
"""

from __future__ import annotations

import time

import numpy as np

from ..mechanics.breaker import Breaker
from ..mechanics.effects import EFFECT_NAMES
from .answer_set import AnswerSet, answer_set
from .decision import decide
from .errors import DiagnosisError
from .evidence import evidence
from .hypotheses import catalogue_for
from .linearised import fit_reported, holdout_shrink
from .predictive import score
from .measurement import next_measurement
from .none_test import none_test
from .report import build, message, set_report
from .scorer import OUTSIDE, shipped
from .windows import prepare

__all__ = ["diagnose", "DiagnosisError"]


def diagnose(captures, breaker: Breaker, operation: str, *, effects=None, seed: int = 1,
             fitter=None, next_measurements: bool = True, strengths: dict | None = None,
             features: bool = False, features_only: bool = False) -> dict:
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
    features : bool
        Also return every hypothesis's features (``features.collect``) as ``features``.
    features_only : bool
        Stop after the features (the gap corpus: what the scorer is trained on); returns
        ``{"features", "stages_s"}`` only.

    Returns
    -------
    dict : the result contract (docs/diagnosis.md).
    """
    t0 = time.perf_counter()
    clock = StageClock()
    if operation not in ("open", "close"):
        raise DiagnosisError(f"operation must be 'open' or 'close', got {operation!r}")
    unknown = [n for n in (effects or []) if n not in EFFECT_NAMES]
    if unknown:
        raise DiagnosisError(f"unknown effect(s) {', '.join(unknown)}; known: {', '.join(EFFECT_NAMES)}")
    catalogue = catalogue_for(operation, effects)
    if not catalogue:
        raise DiagnosisError(f"none of the given effects acts on an {operation} operation")
    windows = prepare(list(captures), breaker, operation, fitter=fitter, seed=seed)
    clock.lap("prepare")
    try:
        if features_only:
            scores = score(windows, catalogue)
            clock.lap("evidence")
            return {"features": scores.features, "left_out": list(getattr(windows, "left_out", []) or []),
                    "none_test": none_test(windows).to_dict(),
                    "stages_s": clock.walls(), "stages": clock.stages}
        return _diagnose(windows, catalogue, strengths, next_measurements, t0, clock, features)
    except (ArithmeticError, np.linalg.LinAlgError) as exc:
        # a numerical failure (a singular system, an overflow): said in words naming the records
        # and what failed where. Any other error is a fault of the method and is not dressed up
        # as a refusal (issue 48 item 6)
        raise DiagnosisError(refusal(windows, exc)) from None


REFIT_MEMBERS = 3   # the set's members holding effects reported with a joint refit (how far the gap shrinks)


class StageClock:
    """Wall, CPU (the process's, both threads) and compiled model integrations
    (``mechanics.effects.integrator.tally``) per stage of one diagnosis."""

    def __init__(self):
        self.stages = {}
        self._mark = self._now()

    @staticmethod
    def _now():
        from ..mechanics.effects.integrator import tally

        t = tally()
        return time.perf_counter(), time.process_time(), t["trajectories"], t["seconds"], t["coarse"]

    def lap(self, name: str) -> None:
        now = self._now()
        w, c, n, k, g = (a - b for a, b in zip(now, self._mark))
        self.stages[name] = {"wall_s": w, "cpu_s": c, "integrations": int(n), "coarse_integrations": int(g),
                             "kernel_s": k}
        self._mark = now

    def walls(self) -> dict:
        return {k: v["wall_s"] for k, v in self.stages.items()}


def decide_none(nt, probs: dict, sc):
    """The answer's set with ``none`` decided by the test ``nt`` (``none_test``) before the
    scorer: consistent with the noise → ``none``, a set of one (the scorer's probabilities kept
    beside it, for the reader); refused → ``none`` leaves the set, its probability 0, and the
    others are the scorer's conditioned on "not none" (p / (1 − p_none)), the set built on them."""
    ranked = dict(sorted(probs.items(), key=lambda kv: (-kv[1], kv[0])))
    if nt.consistent:
        return AnswerSet("none", float(probs.get("none", 0.0)), ["none"], 1.0 - sc.alpha, "none", True, ranked,
                         float(sc.qhat), sc.lam)
    z = sum(v for k, v in probs.items() if k != "none")
    rest = {k: (v / z if z > 0 else 0.0) for k, v in probs.items() if k != "none"}
    aset = answer_set(rest, sc.qhat, sc.lam, sc.alpha)
    aset.probabilities["none"] = 0.0
    return aset


def _diagnose(windows, catalogue, strengths, next_measurements, t0, clock, features=False):
    nt = none_test(windows)
    scores = score(windows, catalogue)
    clock.lap("evidence")
    sc = shipped()
    probs = sc.predict_proba(scores.features)
    aset = decide_none(nt, probs, sc)
    scores.weights = dict(aset.probabilities)
    # the report's joint refits: the evidence's exact fits are reused (no integration); a member
    # the evidence did not refit exactly is fitted only when it is the answer (the report needs
    # its fit), the others say how far the gap shrinks by the linear fit of their shapes
    # (``report.set_report``)
    exact = getattr(scores, "exact", {}) or {}
    members = [k for k in aset.members if k not in ("none", OUTSIDE)
               and (k in exact or k == aset.top)][:REFIT_MEMBERS]
    fits = fit_reported(windows, scores, names=members)
    clock.lap("report_refit")
    ev = evidence(fits, scores)
    dec = decide(fits, ev, aset, catalogue, strengths)
    nm = next_measurement(fits, dec.rivals) if (next_measurements and dec.status == "ambiguous") else []
    ho = holdout_shrink(windows, fits.hypotheses[dec.hypothesis]) if dec.status == "named" else None
    result = build(fits, ev, dec, nm, ho, time.perf_counter() - t0, scores)
    result.update(set_report(aset, fits, scores.features, sc))
    result["none_test"] = nt.to_dict()
    result["message"] = message(result)
    clock.lap("rest")
    result["stages_s"] = clock.walls()
    result["stages"] = clock.stages
    if features:
        result["features"] = scores.features
    return result


STAGES = {"predictive": "the evidence (each hypothesis's leave-one-capture-out score)",
          "linearised": "the joint refit of the hypotheses", "hypotheses": "the joint refit of the hypotheses",
          "evidence": "the noise model of the report", "discrepancy": "the outside-the-catalogue term",
          "report": "the report", "measurement": "the next-measurement advice", "decision": "the decision",
          "windows": "the reduced fit's linearisation"}


def refusal(windows, exc) -> str:
    """The words of a refusal after a numerical failure: per record, what in its own data is not
    a number (its samples, its reduced fit's residual, its Jacobian), else the stage of the method
    that failed and how (a singular system, a value that is not a number made by the method)."""
    import traceback

    bad = []
    for cw in windows.captures:
        what = [label for label, v in (("its samples", cw.data.y), ("its reduced fit's state", cw.x),
                                       ("its noise weights", cw.data.weight), ("its reduced fit's residual", cw.r),
                                       ("its state Jacobian", cw.J)) if not np.all(np.isfinite(v))]
        if what:
            bad.append(f"{cw.data.source}: {', '.join(what)} not a number")
    if bad:
        return "; ".join(bad) + ": refused, no diagnosis"
    stage = "the method"
    for fr in reversed(traceback.extract_tb(exc.__traceback__)):
        mod = fr.filename.replace("\\", "/").rsplit("/", 1)[-1].removesuffix(".py")
        if "/diagnosis/" in fr.filename.replace("\\", "/") and mod in STAGES:
            stage = STAGES[mod]
            break
    how = ("a linear system had no unique solution" if isinstance(exc, np.linalg.LinAlgError)
           else "a value that is not a number was made inside it" if "nan" in str(exc).lower() or "inf" in str(exc).lower()
           else "an arithmetic failure" if isinstance(exc, ArithmeticError) else "an invalid intermediate value")
    names = ", ".join(c.data.source for c in windows.captures)
    return (f"{names}: the records' samples and reduced fits are numbers, but {stage} failed on them ({how}): "
            f"refused, no diagnosis; please report it with the records")
