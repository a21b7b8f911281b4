"""Issue 57: no NaN or infinity ever reaches ``hvcb fit --json``; a record with masked spans,
infinities or NaN samples fits, or is refused in words. The records are written here (the
analyser layout of shared/realworld/analyser-csv, three poles wired)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from service.cli import main
from service.estimation.finite import finite_tree

from tests.analyser.export_gen import Spec, export_text

GENERIC = "config/breakers/generic-analyser.toml"
RATE = 10_000.0
COL = {"C4": 3, "T1": 7, "T2": 8, "T3": 9, "R1": 14}  # columns of the layout's sample table


def _strict(text: str):
    def refuse(word):
        raise ValueError(f"not strict JSON: {word}")
    return json.loads(text, parse_constant=refuse)


def _with(text: str, marks: list[tuple[str, float, float, str]]) -> str:
    """``text`` with column ``name``'s samples from ``t0`` to ``t1`` [s] written as ``word``."""
    lines = text.split("\n")
    head = next(i for i, line in enumerate(lines) if line.startswith("Coil Current C1"))
    for i in range(head + 1, len(lines)):
        if not lines[i]:
            continue
        t = (i - head - 1) / RATE
        fields = lines[i].split(",")
        for name, t0, t1, word in marks:
            if t0 <= t <= t1:
                fields[COL[name]] = word
        lines[i] = ",".join(fields)
    return "\n".join(lines)


def test_a_value_json_cannot_hold_is_null_with_its_reason():
    out = finite_tree({"fitness": float("inf"), "latch_time_s": float("nan"), "peak": np.float64(1.5),
                       "dip_s": float("nan"), "dip_s_reason": "no dip", "rows": [np.nan, 2.0, np.int64(3)],
                       "ok": np.bool_(True)})
    assert out["fitness"] is None and "∞" in out["fitness_reason"]
    assert out["latch_time_s"] is None and "NaN" in out["latch_time_s_reason"]
    assert out["dip_s"] is None and out["dip_s_reason"] == "no dip"  # a stated reason is kept
    assert out["peak"] == 1.5 and out["rows"] == [None, 2.0, 3] and out["ok"] is True
    _strict(json.dumps(out, allow_nan=False))


CASES = {
    "NaN samples in the trip coil's pulse": [("C4", 0.306, 0.3065, "NaN")],
    "infinities in the trip coil's pulse": [("C4", 0.306, 0.3065, "∞")],
    "a trip coil that is NaN throughout": [("C4", 0.0, 1.0, "NaN")],
    "an infinite DCRM span in the motion": [("R1", 0.31, 0.33, "∞")],
    "a masked travel span at rest": [("T1", 0.2, 0.21, "NaN")],
    "a masked span on one pole in the window": [("T1", 0.33, 0.331, "-∞")],
    "the first and last samples masked": [("T1", 0.0, 0.001, "NaN"), ("T1", 0.399, 0.4, "inf")],
}


@pytest.mark.parametrize("marks", list(CASES.values()), ids=list(CASES))
def test_a_close_open_record_with_missing_samples_fits_as_strict_json(tmp_path, capsys, marks):
    text, truth = export_text(Spec(wired_travel=(1, 2, 3)))
    path = tmp_path / "rec.csv"
    path.write_text(_with(text, marks), encoding="utf-8")
    assert main(["fit", str(path), "--breaker", GENERIC, "--operation", "open", "--json"]) == 0
    out = _strict(capsys.readouterr().out)
    assert all(math.isfinite(v) for v in out["parameters"].values())
    assert out["parameters"]["DO"] == pytest.approx(truth["params"]["DO"], rel=0.2)


def test_every_pole_masked_in_the_window_is_refused_in_words(tmp_path, capsys):
    text, _ = export_text(Spec(wired_travel=(1, 2, 3)))
    path = tmp_path / "rec.csv"
    path.write_text(_with(text, [(p, 0.33, 0.331, "NaN") for p in ("T1", "T2", "T3")]), encoding="utf-8")
    assert main(["fit", str(path), "--breaker", GENERIC, "--operation", "open", "--json"]) == 2
    cap = capsys.readouterr()
    assert cap.out == ""  # nothing half-written on stdout
    assert "over-range" in cap.err and "T1" in cap.err and "window" in cap.err
    assert "array must not" not in cap.err and "JSON compliant" not in cap.err


def test_a_library_refusing_a_nan_is_answered_in_words(tmp_path, capsys, monkeypatch):
    """The net under the fit: scipy's own words for a NaN met inside it never reach the user."""
    text, _ = export_text(Spec(wired_travel=(1,)))
    path = tmp_path / "rec.csv"
    path.write_text(text, encoding="utf-8")

    def scipy_refuses(*a, **k):
        raise ValueError("array must not contain infs or NaNs")
    monkeypatch.setattr("service.estimation.fit.fit_capture", scipy_refuses)
    assert main(["fit", str(path), "--breaker", GENERIC, "--operation", "open", "--json"]) == 2
    err = capsys.readouterr().err
    assert "cannot compute" in err and str(path) in err and "array must not" not in err
