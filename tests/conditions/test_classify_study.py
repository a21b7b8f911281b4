"""The quick `classify` study (Table 9 under field nuisance, two protocols) and its classifiers."""

import json

import numpy as np
import pytest

from service.studies import classify
from service.studies.classification_methods import FIELD_NUISANCE, classification_spec
from service.studies.condition_classifiers import NearestNominal, train_test
from service.studies.condition_cnn import CNN1D, torch_available
from service.studies.condition_data import DatasetSpec, setting_parameters


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("classify")
    return out, classify.run(out, quick=True)


def test_json_has_both_protocols_the_four_methods_and_the_nuisance(study):
    out, _ = study
    data = json.loads((out / "classify.json").read_text())
    methods = {"proposed", "svm", "bpnn"} | ({"cnn"} if torch_available()[0] else set())
    assert set(data["protocols"]) == {"cv5", "cross_unit"}
    for proto, n in (("cv5", data["samples"]["unit1"]), ("cross_unit", data["samples"]["unit2"])):
        assert set(data["protocols"][proto]) == methods
        for m in methods:
            acc = data["protocols"][proto][m]
            conf = np.array(data["confusion"][proto][m])
            assert 0.0 <= acc <= 1.0
            # Every sample is tested once; the diagonal is the accuracy (rejected fits count wrong).
            assert conf.sum() <= n and conf.trace() == pytest.approx(acc * n)
    assert data["seed"] == 2026
    nz = data["nuisance"]
    assert nz["friction_TOf"] == FIELD_NUISANCE["friction_spread"]
    assert nz["trigger_delay_s"] == list(FIELD_NUISANCE["trigger_delay_s"])
    lo, hi = nz["drawn_range"]["trigger_delay_s"]
    assert FIELD_NUISANCE["trigger_delay_s"][0] <= lo < hi <= FIELD_NUISANCE["trigger_delay_s"][1]
    lo, hi = nz["drawn_range"]["snr_db"]
    assert 40.0 <= lo < hi <= 55.0
    assert set(data["acceptance"]) == {"cv5 proposed >= 98.3 %", "cross_unit proposed >= 95.0 %"}
    md = (out / "classify.md").read_text()
    assert "paper Table 9" in md and "98.3" in md and "cross_unit" in md
    assert (out / "classify_confusion.png").exists()
    assert len(list(out.glob("dataset-open-*.npz"))) == 4, "two units, main set and one sweep level"


def test_with_little_friction_spread_the_proposed_method_separates_the_settings(study):
    _, res = study
    # TOf ±1 % moves BO by a fifth of a nut step: the settings separate, on both units.
    low = res["friction_sweep"]["0.01"]
    assert low["bo_spread"]["within_sd_in_steps"] < 0.5
    assert low["cv5"]["proposed"] >= 0.8 and low["cross_unit"]["proposed"] >= 0.8
    # At the main ±10 % the friction alone spreads BO by about one step (why the accuracy falls).
    assert res["bo_spread"]["friction_sd"] > 0.7 * res["bo_spread"]["design_step"]


def test_the_nut_setting_moves_only_bo_in_the_design():
    assert setting_parameters(classification_spec(quick=True)) == ("BO",)
    assert setting_parameters(DatasetSpec(operation="close")) == ()


def test_design_nominal_vectors_ignore_a_unit_offset_in_the_other_parameters():
    rng = np.random.default_rng(1)
    y = np.repeat(np.arange(4), 25)
    # Column 0 (BO-like) carries the setting; column 1 (AO-like) drifts a little with it.
    X = np.column_stack([100.0 * y + rng.normal(0, 20, y.size), 40.0 * y + rng.normal(0, 20, y.size)])
    shifted = X + np.array([0.0, 400.0])  # another unit: AO 20 sd higher, BO as designed
    design = train_test(lambda: NearestNominal("within", setting_columns=[0]), X, y, shifted, y)
    free = train_test(lambda: NearestNominal("within"), X, y, shifted, y)
    assert design["accuracy"] > 0.95
    assert free["accuracy"] < 0.6  # the free rule drags every sample to the setting with the highest AO


def test_cnn_learns_a_separable_problem():
    ok, why = torch_available()
    if not ok:
        print(f"SKIP: {why}")
        pytest.skip(why)
    rng = np.random.default_rng(0)
    y = np.repeat(np.arange(3), 20)
    t = np.linspace(0, 1, 64)
    # Travel-like ramps whose onset differs by class, with noise.
    X = np.tanh((t - 0.3 - 0.2 * y[:, None]) / 0.05) + rng.normal(0, 0.2, (y.size, t.size))
    clf = CNN1D(seed=0, quick=True).fit(X, y)
    assert np.mean(clf.predict(X) == y) > 0.8
