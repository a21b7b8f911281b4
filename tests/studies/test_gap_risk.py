"""The risk-control and conformal layer of the gap study (service/studies/gap/risk.py)."""

import numpy as np
import pytest

from service.studies.gap import risk


def _row(proto, truth, probs, dchi2=1e4, shrink=0.9, outside=False):
    return {"prototype": proto, "truth": truth, "outside": outside, "probabilities": probs,
            "oracle": {"delta_chi2": dchi2}, "gap": {"shrink": shrink}}


def test_true_labels():
    assert risk.true_label(_row("a", [], {})) == "none"
    assert risk.true_label(_row("a", ["rod_elasticity"], {}, dchi2=50)) == "none"       # undetectable
    assert risk.true_label(_row("a", ["rod_elasticity"], {})) == "rod_elasticity"
    assert risk.true_label(_row("a", ["b_x", "a_y"], {})) == "a_y+b_x"
    assert risk.true_label(_row("a", [], {}, outside=True)) == "unexplained"


def test_conformal_quantile_and_set():
    s = np.linspace(0.0, 0.99, 100)
    q = risk.conformal_quantile(s, 0.1)
    assert q == pytest.approx(s[90])                       # ⌈101·0.9⌉ = 91st smallest
    assert risk.conformal_quantile([0.1, 0.2], 0.1) == float("inf")       # too few to certify
    assert risk.prediction_set({"none": 0.7, "x": 0.25, "y": 0.05}, 0.8) == ["none", "x"]
    assert risk.prediction_set({"none": 0.7, "x": 0.25}, 0.1) == ["none"]  # never empty


def test_hb_pvalue_monotone_and_known_values():
    assert risk.hb_pvalue(0.0, 100, 0.05) == pytest.approx(min(0.95 ** 100, np.e * 0.95 ** 100))
    assert risk.hb_pvalue(0.0, 200, 0.05) < risk.hb_pvalue(0.0, 50, 0.05)
    assert risk.hb_pvalue(0.2, 100, 0.05) == 1.0 or risk.hb_pvalue(0.2, 100, 0.05) > 0.9
    assert risk.hb_pvalue(0.01, 300, 0.05) < 0.01


def test_learn_then_test_names_only_when_certified():
    rng = np.random.default_rng(0)
    good = [_row("a", ["rod_elasticity"], {"rod_elasticity": 0.97, "none": 0.03}) for _ in range(120)]
    rule = risk.learn_then_test(good)
    assert rule["margin"] is not None and rule["share"] >= risk.MATERIAL
    # half of the confident names wrong: nothing is certified, so nothing is named
    bad = [_row("a", ["rod_elasticity"] if rng.random() < 0.5 else ["puffer_gas"],
                {"rod_elasticity": 0.97, "none": 0.03}) for _ in range(120)]
    assert risk.learn_then_test(bad)["margin"] is None


def test_material_or_nothing():
    r = _row("a", ["rod_elasticity"], {"rod_elasticity": 0.99, "none": 0.01}, shrink=0.3)
    assert risk.names(r, 0.0, 0.0) is None                 # explains under half of the gap: never named
    r["gap"]["shrink"] = 0.8
    assert risk.names(r, 0.0, 0.0) == "rod_elasticity"


def test_lopo_holds_out_the_prototype():
    rows = [_row(p, ["rod_elasticity"], {"rod_elasticity": 0.97, "none": 0.03}) for p in "ab" for _ in range(80)]
    rows[0]["probabilities"] = {"rod_elasticity": 0.0, "none": 1.0}      # one odd group in a
    res = risk.lopo(rows)
    assert res["a"]["n_calibration"] == 80 and res["b"]["n_calibration"] == 80
    # a's calibration is b's rows alone: a's odd group does not move a's own q̂
    assert res["a"]["qhat"] == pytest.approx(0.03)
    f = risk.figures(res["a"]["answers"])
    assert f["set_holds_truth_detectable"] == (79, 80)
