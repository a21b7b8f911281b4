"""The gap study's detectability oracle on tiny groups, and the study end to end at its smallest."""

import copy
import json

import numpy as np
import pytest

from service.prototypes.a.effects import REALISTIC
from service.prototypes.a.groups import draw_conditions, make_unit, simulate_capture
from service.studies.common import load_reference
from service.studies.gap.oracle import DETECTABLE_CHI2, same_length, ar_whitener, chi2, group_oracle


def _group(effects, n=2, seed=3):
    rng = np.random.default_rng(seed)
    unit = make_unit(rng, effects=effects)
    caps, cleans, healthies = [], [], []
    for _ in range(n):
        cond = draw_conditions(rng)
        twin = copy.deepcopy(rng)
        cap, _ = simulate_capture(unit, "open", conditions=cond, rng=rng)
        caps.append(cap)
        cleans.append(simulate_capture(unit, "open", conditions=cond, rng=copy.deepcopy(twin), noise_rad=0.0)[0].travel)
        h = simulate_capture({**unit, "effects": {}}, "open", conditions=cond, rng=copy.deepcopy(twin), noise_rad=0.0)[0]
        healthies.append(same_length(h.travel, cap.travel.size))
    return caps, cleans, healthies


def test_a_strong_effect_is_detectable_and_a_healthy_group_is_not():
    b = load_reference()
    strong = group_oracle(*_group({"orifice_buffer": REALISTIC["orifice_buffer"]}), b, "open")
    assert strong["detectable"] and strong["delta_chi2"] > 10 * DETECTABLE_CHI2
    assert strong["bias"]["DO"] > 0.2          # the orifice force is soaked up by the buffer damping DO
    assert abs(strong["healthy_delta_chi2"]) < DETECTABLE_CHI2
    healthy = group_oracle(*_group({}), b, "open")
    assert not healthy["detectable"]
    # the reduced fit overfits the noise by about its free parameters, never by a hundred
    assert -40 < healthy["delta_chi2"] < 20
    assert abs(healthy["bias"]["DO"]) < 1e-6 and healthy["unit_alpha0"] == pytest.approx(b.alpha0, rel=0.05)


def test_the_noise_model_whitens_coloured_noise():
    rng = np.random.default_rng(0)
    w = rng.normal(0, 1e-3, 20000)
    e = np.zeros_like(w)
    for i in range(2, w.size):                        # AR(2): a resonance
        e[i] = 1.2 * e[i - 1] - 0.5 * e[i - 2] + w[i]
    a, sd = ar_whitener(e)
    assert a[:2] == pytest.approx([1.2, -0.5], abs=0.03) and sd == pytest.approx(1e-3, rel=0.03)
    assert chi2(e, a, sd) == pytest.approx(e.size, rel=0.05)     # white χ² would be ~ var(e)/var(w) times more
    with pytest.raises(ValueError, match="identically zero"):
        ar_whitener(np.zeros(100))


def test_gap_study_writes_its_files(tmp_path):
    from service.studies.gap import rescore, run_gap_study

    sizes = {"per_effect": 0, "controls": 1, "two_effect": 0, "outside": 0, "captures_per_group": 2}
    r = run_gap_study(tmp_path, seed=11, workers=1, prototypes=["a"], sizes=sizes)
    for name in ("gap_groups.json", "gap_calibration.json", "gap.md", "a/manifest.json"):
        assert (tmp_path / name).exists(), name
    g = json.loads((tmp_path / "gap_groups.json").read_text())
    row = g["rows"][0]
    assert g["complete"] is True and len(g["rows"]) == 1 and row["truth"] == [] and len(row["stems"]) == 2
    assert row["oracle"]["detectable"] is False and "delta_chi2" in row["oracle"]
    assert r["per_prototype"]["a"]["none_on_healthy"]["n"] == 1
    assert "| healthy → none |" in (tmp_path / "gap.md").read_text()
    assert rescore(tmp_path)["per_prototype"] == r["per_prototype"]
