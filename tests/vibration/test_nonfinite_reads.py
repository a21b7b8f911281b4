"""Issue 57's leads: a NaN or an infinity in a coil channel or met inside the vibration read never
reaches a threshold, a fit's answer or its JSON; the record is read, or the read says in words why not.
The records are written here: the analyser layout (tests/analyser/export_gen.py) as a capture,
with the defect put into its samples."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from drivers.capture import AuxChannel
from service.acquisition.capture_file import read_capture
from service.acquisition.coil_trigger import _coil_rises
from service.breaker_file import load_breaker
from service.estimation.fit import fit_capture
from tests.analyser.export_gen import Spec, export_text
from tests.conftest import REPO

GENERIC = REPO / "config" / "breakers" / "generic-analyser.toml"


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    text, truth = export_text(Spec(wired_travel=(1,)))
    path = tmp_path_factory.mktemp("rec") / "co.csv"
    path.write_text(text, encoding="utf-8")
    breaker = load_breaker(GENERIC)
    return read_capture(path, to_rad=breaker.travel_map.to_rad), breaker, truth


def _with_coil(cap, name, data):
    aux = tuple(dataclasses.replace(a, data=data) if a.name == name else a for a in cap.aux)
    return dataclasses.replace(cap, aux=aux)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_coil_with_non_finite_samples_still_gives_its_rise(record, bad):
    cap, _, _ = record
    clean = dict(_coil_rises(cap))
    c4 = np.asarray(next(a for a in cap.aux if a.name == "C4").data, float).copy()
    i = int(clean["C4"][0])
    c4[i + 20: i + 25] = bad  # inside the pulse
    c4[10:12] = bad  # and at rest
    rises = dict(_coil_rises(_with_coil(cap, "C4", c4)))
    assert "C4" in rises and list(rises["C4"]) == list(clean["C4"])


def test_a_coil_that_is_no_reading_throughout_is_left_out(record):
    cap, _, _ = record
    rises = dict(_coil_rises(_with_coil(cap, "C4", np.full(cap.travel.size, np.nan))))
    assert "C4" not in rises and "C1" in rises


def test_a_library_refusing_a_value_inside_the_vibration_read_leaves_the_fit_and_says_so(record, monkeypatch):
    """The fit's net around the vibration and coil read: a value a library refuses there (scipy's
    own words) does not fail the travel fit, and the reason is ours."""
    cap, breaker, truth = record
    opening = dataclasses.replace(cap, meta={**cap.meta})

    def refuses(*a, **k):
        raise ValueError("array must not contain infs or NaNs")
    monkeypatch.setattr("service.vibration.characteristics.record_coils", refuses)
    result = fit_capture(opening, breaker, "open")
    ch = result.characteristics
    assert ch["latch_time_s"] is None
    assert "cannot use" in ch["latch_time_reason"] and "array must not" not in ch["latch_time_reason"]
    assert result.parameters["DO"] == pytest.approx(truth["params"]["DO"], rel=0.2)
    json.dumps(result.to_dict(), allow_nan=False)  # strict JSON
