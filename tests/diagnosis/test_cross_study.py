"""The cross-prototype study (issue 11): prototype B's captures diagnosed blind from COMTRADE,
and the figures computed from the rows."""

import json

import pytest

from service.diagnosis.cross_study import classify_groups, run_cross_study, summarise


def _row(truth, op, verdict, sig=True, dist=True, outside=False, absorbed=False, rank=1):
    return {"truth": truth, "operation": op, "verdict": verdict, "significant_gap": sig,
            "true_distinguishable": dist, "outside": outside, "true_absorbed_reported": absorbed,
            "true_rank": rank, "status": "none" if verdict == "none" else "explained",
            "candidates": [{"effect": truth, "shrink": 0.8}], "runtime_s": 1.0}


def test_figures_from_rows():
    rows = ([_row("orifice_buffer", "open", "orifice_buffer")] * 3 + [_row("orifice_buffer", "open", "unexplained")]
            + [_row("cam_friction", "close", "none", sig=False, dist=False, absorbed=True)] * 2
            + [_row("cam_friction", "close", "viscous_friction", sig=False, dist=False, absorbed=True)]
            + [_row("none", "open", "none", dist=None)] * 4
            + [_row("outside", "open", "unexplained", dist=None, outside=True)])
    cls = classify_groups(rows)
    assert cls == {("orifice_buffer", "open"): "detectable", ("cam_friction", "close"): "absorbed"}
    s = summarise(rows)
    assert s["top1_detectable"] == pytest.approx(0.75)
    assert s["control_none_rate"] == 1.0
    assert s["wrong_name_rate_all"] == pytest.approx(1 / len(rows))
    assert s["absorbed_listed_absorbed"] == 1.0
    assert s["absorbed_wrong_name"] == pytest.approx(1 / 3)
    assert s["outside_named"] == 0 and s["outside_captures"] == 1


def test_small_run_reads_prototype_b_files_blind(tmp_path):
    data = run_cross_study(tmp_path, seed=73, workers=2, per_effect=1, controls=2, outside=1, limit=4)
    on_disk = json.loads((tmp_path / "gap_cross.json").read_text())
    assert on_disk["captures"] == 4 == len(on_disk["rows"])
    assert (tmp_path / "gap_cross.md").read_text().startswith("# Cross-prototype blind gap study")
    # the diagnoser saw only COMTRADE files of prototype B
    assert len(list((tmp_path / "prototype_b").glob("pb*.cfg"))) == 16 + 2 + 2
    for r in data["rows"]:
        assert r["verdict"] != "error", r
        assert r["status"] in ("explained", "partly_explained", "ambiguous", "unexplained", "none")
    # seed 73 starts with a control and a sensor lag (outside the catalogue)
    assert [r["truth"] for r in data["rows"][:2]] == ["none", "outside"]
    assert data["rows"][0]["verdict"] == "none"
    assert data["rows"][1]["verdict"] in ("none", "unexplained")
