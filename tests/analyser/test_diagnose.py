"""The gap diagnosis of an analyser opening: the record is the reduced model's own curve (with
an α0 far from the file's guess and a 15 ms coil-to-motion delay), so the diagnosis must find no
gap. Before the diagnosis took the fit's estimated α0/CO and bounded τ about the fitted delay,
it answered `unexplained` with a gap of ~18× the noise: an artefact of its own baseline."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from service.diagnosis.windows import TAU_SPAN, tau_span, with_estimated_structure

from .test_operations import _record


def test_the_reduced_models_own_analyser_curve_has_no_gap(tmp_path, monkeypatch):
    from service.diagnosis import diagnose
    from service.estimation.record import operation_capture

    from . import export_gen

    base = export_gen.truth
    monkeypatch.setattr(export_gen, "truth", lambda: (dataclasses.replace(base()[0], alpha0=0.85), base()[1]))
    record, b, _ = _record(tmp_path)
    cap = operation_capture(record, b, "open")[0]  # as `hvcb diagnose` cuts it
    out = diagnose([cap], b, "open")
    assert out["answer"] == "none" and "none" in out["set"] and out["effects"] == [], (out["status"], out["answer"])
    assert out["gap"]["gap_sigma"] < 1.5  # the misfit is the noise floor, in noise units


def test_tau_is_bounded_about_the_fitted_delay_only_when_it_lies_outside_the_nominal_span():
    assert tau_span(0.4e-3) == TAU_SPAN  # a prototype's latch: unchanged
    lo, hi = tau_span(13.5e-3)  # an analyser's coil-to-motion delay
    assert lo < 13.5e-3 < hi and hi - lo == pytest.approx(TAU_SPAN[1] - TAU_SPAN[0])


def test_the_estimated_structure_is_the_median_over_the_captures_and_a_known_design_is_kept():
    from service.breaker_file import load_breaker
    from tests.conftest import BREAKER_FILE

    b = load_breaker(BREAKER_FILE)

    class Fit:
        def __init__(self, structure):
            self.structure = structure

    fits = [Fit({"alpha0": {"value": a}, "CO": {"value": co}}) for a, co in ((0.80, 90.0), (0.84, 100.0), (0.82, 95.0))]
    got = with_estimated_structure(b, fits)
    assert got.alpha0 == pytest.approx(0.82) and got.CO == pytest.approx(95.0)
    assert with_estimated_structure(b, [Fit({}), Fit({})]) is b
    assert np.isclose(with_estimated_structure(b, [Fit({"alpha0": {"value": 0.6}})]).CO, b.CO)
