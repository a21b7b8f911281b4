"""`hvcb study gap` end to end at the smallest size (one healthy prototype-A group of 2 captures)."""

import json

from service.diagnosis.study import rescore, run_gap_study


def test_gap_study_writes_its_files(tmp_path):
    sizes = {"per_effect": 0, "controls": 1, "two_effect": 0, "outside": 0, "captures_per_group": 2}
    r = run_gap_study(tmp_path, seed=11, workers=1, prototypes=["a"], sizes=sizes)
    for name in ("gap_groups.json", "gap_calibration.json", "gap_single.json", "gap_single.png", "gap.md"):
        assert (tmp_path / name).exists(), name
    g = json.loads((tmp_path / "gap_groups.json").read_text())
    assert g["complete"] is True
    assert len(g["rows"]) == 1 and g["rows"][0]["truth"] == [] and len(g["rows"][0]["stems"]) == 2
    assert r["groups"]["a"]["none_on_healthy"]["n"] == 1
    cal = json.loads((tmp_path / "gap_calibration.json").read_text())
    assert sum(b["n"] for b in cal["pooled"]["group"]["bins"]) == 1
    assert "| A | groups |" in (tmp_path / "gap.md").read_text()
    again = rescore(tmp_path)                      # scoring again from the saved rows
    assert again["groups"] == r["groups"]
