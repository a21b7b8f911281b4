"""Issue 42 item 5: an analyser record valid but for its over-range spans is diagnosed on what is
valid; a numerical failure inside the method is refused naming the records and the real reason."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from service.diagnosis import DiagnosisError, diagnose

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def analyser(tmp_path_factory):
    from drivers.capture_file import read_capture
    from service.acquisition.capture_file import breaker_reading
    from service.breaker_file import load_breaker
    from service.estimation.record import operation_capture
    from tests.analyser.export_gen import Spec, write_export

    b = load_breaker(REPO / "config/breakers/generic-analyser.toml")
    d = tmp_path_factory.mktemp("analyser42")
    caps = []
    for seed in (3, 4):
        path = d / f"rec{seed}.csv"
        write_export(path, Spec(rate=5_000, seed=seed))
        caps.append(operation_capture(read_capture(path, **breaker_reading(b)), b, "open")[0])
    return b, caps


def _masked(cap, at=0.45, n=12):
    """``cap`` with an over-range span in its motion, as the analyser reader carries one: the
    samples filled by a straight line, the span in ``meta['masked']``."""
    from drivers.masked import filled, spans

    y = np.array(cap.travel, float)
    i = int(at * y.size)
    mask = np.zeros(y.size, bool)
    mask[i:i + n] = True
    ch = cap.meta.get("travel_channel", "travel")
    meta = {**cap.meta, "masked": spans(ch, mask, cap.sample_rate)}
    return replace(cap, travel=filled(y, mask), meta=meta)


def test_a_record_with_an_over_range_span_in_its_motion_is_diagnosed_on_what_is_valid(analyser):
    b, caps = analyser
    bad = _masked(caps[1])
    r = diagnose([caps[0], bad], b, "open", next_measurements=False)
    clean = diagnose(caps, b, "open", next_measurements=False)
    assert r["status"] == clean["status"]
    assert clean["blocks"] - 12 <= r["blocks"] < clean["blocks"]     # the masked blocks are not evidence


def test_the_result_says_how_its_probabilities_were_calibrated(analyser):
    from service.diagnosis.report import format_report

    b, caps = analyser
    r = diagnose(caps, b, "open", next_measurements=False)
    from service.diagnosis.scorer import shipped

    note = r["calibration_note"]
    pv = shipped().meta["provenance"]
    assert "docs/gap-study.md" in note and f"on {pv['rows']} simulated groups" in note
    assert "not on real breakers" in note                               # calibrated on simulations only
    assert ("no single answer is named" in note) == (shipped().lam is None)
    assert "_" not in note.replace("docs/gap-study.md", "")             # words, no identifiers
    assert note in format_report(r)


def test_a_failure_inside_the_method_names_the_records_and_the_stage(analyser, monkeypatch):
    """Numbers in, a non-number made by the method: the words say the records are numbers and
    which stage failed, not that the records hold non-numbers."""
    import importlib

    b, caps = analyser
    pred = importlib.import_module("service.diagnosis.predictive")

    def singular(*a, **k):
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(pred, "loo_lpd", singular)
    with pytest.raises(DiagnosisError) as ei:
        diagnose(caps, b, "open", next_measurements=False)
    msg = str(ei.value)
    assert all(c.source in msg for c in caps)
    assert "samples and reduced fits are numbers" in msg and "evidence" in msg
    assert "no unique solution" in msg and "Singular" not in msg and "Error" not in msg

    # any other error is a fault of the method: it is not dressed up as a refusal (issue 48)
    def bug(*a, **k):
        raise ValueError("array must not contain infs or NaNs")

    monkeypatch.setattr(pred, "loo_lpd", bug)
    with pytest.raises(ValueError, match="infs or NaNs") as bug_info:
        diagnose(caps, b, "open", next_measurements=False)
    assert not isinstance(bug_info.value, DiagnosisError)
