"""The gap study's scoring rules (issue 29's Acceptance) on hand-made rows: each rule can fail."""

import pytest

from service.studies.gap.calibration import apply_map, fit_map, lopo
from service.studies.gap.scoring import (absorbed_ok, bias_agrees, both, reliability, right, score, top1,
                                         wilson, wrong)


def row(truth, status, effects=(), answer=None, p=0.95, outside=False, detectable=True, rivals=(),
        absorbed=(), bias=None, prototype="a", raw=None):
    r = {"prototype": prototype, "truth": list(truth), "outside": outside, "status": status,
         "effects": list(effects), "answer": answer or ("+".join(effects) if effects else "none"),
         "answer_probability": p, "rivals": list(rivals), "absorbed": list(absorbed),
         "oracle": {"detectable": detectable, "bias": bias or {}}}
    if raw is not None:
        r["raw_probability"] = raw
    return r


def test_top1_needs_exactly_the_truth_named():
    assert top1(row(["x"], "named", ["x"]))
    assert not top1(row(["x"], "named", ["x", "y"]))
    assert not top1(row(["x"], "ambiguous", answer="x"))


def test_a_wrong_name_is_wrong_even_with_the_truth_among_rivals():
    r = row(["x"], "named", ["y"], rivals=[{"effect": "x", "probability": 0.4}])
    assert wrong(r) and not top1(r)
    assert not wrong(row(["x"], "named", ["x"]))
    assert wrong(row([], "named", ["x"], outside=True))       # outside the catalogue: any name is wrong


def test_two_effects_both_named_or_both_rivals():
    assert both(row(["x", "y"], "named", ["x", "y"]))
    assert both(row(["x", "y"], "ambiguous", answer="x", rivals=[{"effect": "x"}, {"effect": "y+z"}]))
    assert not both(row(["x", "y"], "ambiguous", answer="x", rivals=[{"effect": "x"}, {"effect": "z"}]))
    assert not both(row(["x", "y"], "named", ["x"]))


def test_undetectable_needs_none_absorbed_and_an_agreeing_bias():
    bias = {"CO": 0.10, "AO": 0.01, "tau": 0.9}
    ok = row(["v"], "none", detectable=False, bias=bias,
             absorbed=[{"effect": "v", "bias": {"CO": 0.12, "AO": -0.02}}])
    assert absorbed_ok(ok)
    assert not absorbed_ok({**ok, "absorbed": []})
    assert not absorbed_ok({**ok, "status": "named", "effects": ["v"]})
    assert not absorbed_ok({**ok, "absorbed": [{"effect": "v", "parameter_bias": {"CO": -0.1}}]})   # sign
    assert not absorbed_ok({**ok, "absorbed": [{"effect": "v", "parameter_bias": {"CO": 0.5}}]})    # 5×
    assert bias_agrees({"CO": 0.06}, bias) and not bias_agrees({"CO": 0.04}, bias)


def test_right_follows_the_acceptance():
    assert right(row(["x"], "none", detectable=False))               # undetectable: none is right
    assert not right(row(["x"], "none", detectable=True))
    assert right(row([], "unexplained", answer="outside_catalogue", outside=True))
    assert not right(row([], "none", outside=True))
    assert right(row(["x", "y"], "named", ["x", "y"], answer="x+y"))


def test_score_counts_each_rule():
    rows = [row(["x"], "named", ["x"]), row(["x"], "named", ["y"]), row(["y"], "none", detectable=False),
            row([], "none"), row([], "named", ["x"], p=0.5),
            row(["x", "y"], "ambiguous", answer="x", p=0.6, rivals=[{"effect": "x"}, {"effect": "y"}]),
            row([], "unexplained", answer="outside_catalogue", outside=True), {"prototype": "a", "error": "refused"}]
    for r in rows[:-1]:
        r.setdefault("truth", [])
    rows[-1].update(truth=[], outside=False)
    s = score(rows)
    assert (s["top1_detectable"]["k"], s["top1_detectable"]["n"]) == (1, 2)
    assert s["oracle_detectable"] == {"k": 2, "n": 3}
    assert (s["none_on_healthy"]["k"], s["none_on_healthy"]["n"]) == (1, 2)
    assert (s["wrong_names"]["k"], s["wrong_names"]["n"]) == (2, 7)
    assert (s["two_effect_both"]["k"], s["outside_unexplained"]["k"]) == (1, 1)
    assert (s["undetectable_none"]["k"], s["undetectable_none_absorbed_listed"]["k"]) == (1, 0)
    assert s["undetectable_none_absorbed"]["n"] == 0          # no healthy twin: the bias is not checkable
    # stated ≥ 0.9: x right, y wrong, undetectable none right, healthy none right, outside right
    assert (s["stated_ge_0_9_right"]["k"], s["stated_ge_0_9_right"]["n"]) == (4, 5)
    assert s["errors"] == 1


def test_wilson_interval():
    lo, hi = wilson(18, 20)
    assert lo == pytest.approx(0.699, abs=1e-3) and hi == pytest.approx(0.972, abs=1e-3)
    assert wilson(0, 0) is None and wilson(0, 5)[0] == 0.0


def test_reliability_bins_close_at_one():
    t = reliability([0.2, 0.95, 1.0, 1.0], [False, True, True, False])
    assert [b["n"] for b in t] == [1, 0, 0, 1, 2]
    assert t[-1]["fraction_right"] == 0.5


def _cal_rows():
    rows = []
    for proto, flip in (("a", 0.0), ("b", 0.2), ("c", 0.4)):
        for i in range(10):
            p = 0.5 + 0.05 * i
            ok = i >= 3 + int(10 * flip)
            rows.append(row(["x"], "named", ["x"] if ok else ["y"], answer="x" if ok else "y", p=p, raw=p,
                            prototype=proto))
    return rows


def test_calibration_map_is_monotone():
    m = fit_map(_cal_rows())
    assert m["x"] == sorted(m["x"]) and m["y"] == sorted(m["y"])
    assert 0.0 <= min(m["y"]) and max(m["y"]) <= 1.0 and m["fitted_on"] == ["a", "b", "c"]
    assert apply_map(m, [0.0])[0] == m["y"][0] and apply_map(m, [2.0])[0] == m["y"][-1]


def test_lopo_never_sees_the_scored_prototype(monkeypatch):
    import service.studies.gap.calibration as cal

    seen = []
    real = cal.fit_map
    monkeypatch.setattr(cal, "fit_map", lambda rows: seen.append({r["prototype"] for r in rows}) or real(rows))
    out = lopo(_cal_rows(), ["a", "b", "c"])
    assert seen == [{"b", "c"}, {"a", "c"}, {"a", "b"}]
    assert out["a"]["fitted_on"] == ["b", "c"] and out["a"]["n_test"] == 10
    # a map fitted on B and C (more often wrong at a given p) states less than A's own would
    assert out["a"]["calibrated"][4] < real([r for r in _cal_rows() if r["prototype"] == "a"])["y"][-1]


def test_summary_calibrates_held_out_prototypes_by_the_development_map(tmp_path):
    """E (blind, issue 36) is held out; D is a development prototype since issue 36."""
    from service.studies.gap.report import summarise

    rows = _cal_rows() + [dict(r, prototype="e") for r in _cal_rows()[:10]]
    meta = {"seed": 1, "sizes": {}, "prototypes": ["a", "b", "c", "e"]}
    s = summarise(tmp_path, rows, meta)
    lopo_ = s["calibration"]["lopo"]
    assert lopo_["b"]["fitted_on"] == ["a", "c"] and lopo_["e"]["fitted_on"] == ["a", "b", "c"]
    assert s["calibration"]["map_all_development"]["n"] == 30        # E's rows never enter the map
    assert "E calibrated on A+B+C" in (tmp_path / "gap.md").read_text()
    assert s["per_prototype"]["e"]["top1_all_single"]["n"] == 10


def test_stated_gap_reduction_against_the_oracle():
    from service.studies.gap.scoring import shrink_ratios, stated_reduction

    r = {"gap": {"before_rms_rad": 2.0, "after_rms_rad": 1.0, "noise_rad": 1.0}, "blocks": 100,
         "noise_model": {"samples_per_block": 16.0}, "oracle": {"delta_chi2": 4000.0}}
    assert stated_reduction(r) == (4.0 - 1.0) * 100 * 16            # 4800
    s = shrink_ratios([r, dict(r, oracle={"delta_chi2": 2000.0})])
    assert s["ratios"] == [1.2, 2.4] and s["k"] == 1 and s["n"] == 2
