"""The quick `classify` study (Table 9 under field nuisance, two protocols) and its classifiers."""

import dataclasses
import json

import numpy as np
import pytest

from service.studies import classify
from service.studies.classification_methods import FIELD_NUISANCE, classification_spec
from service.studies.condition_classifiers import NearestNominal, train_test
from service.studies.condition_cnn import CNN1D, torch_available
from service.studies.common import load_reference
from service.studies.condition_data import DatasetSpec, make_capture, setting_parameters, stop_to_stop_gain
from service.studies.pair_setting import PairSetting


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("classify")
    return out, classify.run(out, quick=True)


def test_json_has_both_protocols_the_four_methods_and_the_nuisance(study):
    out, _ = study
    data = json.loads((out / "classify.json").read_text())
    methods = {"proposed", "svm", "bpnn"} | ({"cnn"} if torch_available()[0] else set())
    assert set(data["protocols"]) == {"cv5", "cross_unit", "cv5_pair", "cross_unit_pair",
                                      "cross_unit_pair_commissioned"}
    for proto, n in (("cv5", data["samples"]["unit1"]), ("cross_unit", data["samples"]["unit2"]),
                     ("cv5_pair", data["samples"]["unit1"]), ("cross_unit_pair", data["samples"]["unit2"]),
                     ("cross_unit_pair_commissioned", data["samples"]["unit2"] - 1)):
        assert set(data["protocols"][proto]) == methods
        for m in methods:
            acc = data["protocols"][proto][m]
            conf = np.array(data["confusion"][proto][m])
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
    assert set(data["acceptance"]) == {"cv5 proposed >= 98.3 %", "cross_unit proposed >= 95.0 %",
                                       "cv5_pair proposed >= 95.0 %", "cross_unit_pair proposed >= 90.0 %",
                                       "cross_unit_pair_commissioned proposed >= 90.0 %"}
    # Each verdict is its protocol's accuracy against its target, not a stored word.
    for proto, target in data["target"].items():
        assert data["acceptance"][f"{proto} proposed >= {100 * target:.1f} %"] == \
            (data["protocols"][proto]["proposed"] >= target), proto
    assert set(data["ceiling"]) == {"single_opening_true_BO", "pair_true_BO_CC"}
    md = (out / "classify.md").read_text()
    assert "paper Table 9" in md and "98.3" in md and "cross_unit_pair" in md and "identifiability" in md
    assert (out / "classify_confusion.png").exists()
    assert len(list(out.glob("dataset-open-*.npz"))) == 6, "two units: main set, one sweep level, pairs"
    assert len(list(out.glob("dataset-close-*.npz"))) == 2, "the pairs' closings of both units"


def test_the_pair_separates_the_settings_where_one_opening_cannot(study):
    _, res = study
    ident = res["identifiability"]["sets"]
    # One opening sees only P − f·TOf, one closing only P + f·TCf: rank 1 each; the pair, rank 2.
    assert ident["opening"]["rank"] == 1 and ident["closing"]["rank"] == 1 and ident["pair"]["rank"] == 2
    assert ident["opening"]["combination"]["f"] < 0 < ident["closing"]["combination"]["f"]
    assert ident["pair"]["sd_P_steps"] < 0.5
    # On the simulator's true values the pair reads the setting exactly, one opening does not.
    ce = res["ceiling"]
    assert ce["pair_true_BO_CC"]["cv5"] == 1.0
    assert ce["single_opening_true_BO"]["cv5"] < 0.9
    # The fitted pairs: the proposed rule beats the single-opening one on the same unit.
    assert res["protocols"]["cv5_pair"]["proposed"] > res["protocols"]["cv5"]["proposed"]
    # With the unit's spring rate free, the pair's BO and CC are rank 2 in (P, f, κ); AO makes it 3.
    ko = res["identifiability"]["kO_free"]
    assert ko["sets"]["pair BO, CC"]["rank"] == 2 and ko["sets"]["pair AO, BO, CC"]["rank"] == 3
    assert ko["steps_per_kO_percent"] == pytest.approx(0.423, abs=1e-3)
    si = res["setting_inference"]
    assert si["kO_from_AO"]["kappa_drawn"] == pytest.approx(res["unit2_constants"]["kO"])
    # The coverage is a share of the commissioned unit's n readings: a whole count of them.
    phys = si["physical"]["unit2_commissioned"]
    assert phys["n"] > 0
    assert phys["coverage_95"] * phys["n"] == pytest.approx(round(phys["coverage_95"] * phys["n"]), abs=1e-9)


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


def test_a_pair_shares_its_breaker_state_and_sensor_and_the_closing_measures_the_gain():
    opening = classification_spec(quick=True, pair=True)
    closing = dataclasses.replace(opening, operation="close")
    (_, t_open, fit_breaker, n_open), (cap, t_close, _, n_close) = (
        make_capture(s, 2, 1, details=True) for s in (opening, closing))
    assert n_open["friction_factor"] == n_close["friction_factor"] != 1.0
    assert n_open["gain"] == n_close["gain"] and n_open["offset_rad"] == n_close["offset_rad"]
    assert n_open["trigger_delay_s"] != n_close["trigger_delay_s"]
    assert fit_breaker.xO1 == load_reference().xO1, "the fit is not told the setting"
    assert stop_to_stop_gain(cap, fit_breaker) == pytest.approx(n_close["gain"], abs=1e-3)
    # The nut's two steps of pre-load: 2·kO·Δx·rO/J2 in both BO and CC above the design.
    step = 2 * 130000.0 * 3.5e-3 * 0.08 / 0.243
    design = load_reference().design_parameters()
    f = n_open["friction_factor"]
    assert t_open["BO"] == pytest.approx(design["BO"] + step - (f - 1) * 600.0 / 0.243)
    assert t_close["CC"] == pytest.approx(design["CC"] + step + (f - 1) * 1600.0 / 0.243)


def test_pair_setting_reads_the_setting_through_a_friction_that_moves_two_parameters_apart():
    rng = np.random.default_rng(3)
    y = np.repeat(np.arange(5), 40)
    f = rng.uniform(-1, 1, y.size)  # friction: one step's worth, opposite signs in the two columns
    X = np.column_stack([y - 1.5 * f, y + 4.0 * f]) * 150.0 + rng.normal(0, 5, (y.size, 2))
    # The design's dCC/df is 600 per unit f and its step 150: the fitted step says the "fit" reads
    # CC at 1.2 times its change, so the friction is scaled back by that response.
    X[:, 1] *= 1.2
    model = PairSetting(friction=(600.0, 150.0)).fit(X, y)
    k, sd = model.infer(X)
    assert np.mean(model.predict(X) == y) == 1.0 and np.all(sd < 0.1)
    assert np.std(k - y) == pytest.approx(sd[0], rel=0.3)
    assert np.std(model.friction(X) - (f - f.mean())) < 0.05
    one = PairSetting().fit(X[:, :1], y)  # one column alone: the friction is not separable
    assert np.mean(one.predict(X[:, :1]) == y) < 0.8


def test_a_commissioning_pair_removes_a_units_offset():
    """Unit 2 reads 0.5 steps high (its spring rate); one of its pairs at a known setting
    measures that offset, and the others are read right."""
    from service.studies.pair_setting import CommissionedPairSetting

    rng = np.random.default_rng(5)
    y = np.repeat(np.arange(5), 30)
    X1 = np.column_stack([y, y]) * 150.0 + rng.normal(0, 5, (y.size, 2))
    X2 = np.column_stack([y + 0.5, y + 0.5]) * 150.0 + rng.normal(0, 5, (y.size, 2))
    plain = PairSetting().fit(X1, y)
    assert np.mean(plain.predict(X2) == y) < 0.6
    ref = int(np.flatnonzero(y == 2)[0])
    c = CommissionedPairSetting(X2[ref], 2).fit(X1, y)
    assert c.offset_ == pytest.approx(0.5, abs=0.1)
    rest = np.arange(y.size) != ref
    assert np.mean(c.predict(X2[rest]) == y[rest]) == 1.0
    _, sd = c.infer(X2)
    assert sd[0] == pytest.approx(np.sqrt(2) * plain.sd_steps_)


def test_the_spring_rate_is_not_identifiable_from_bo_and_cc_and_one_known_pair_fixes_it():
    from service.studies.common import load_reference
    from service.studies.pair_setting import identifiability_kO

    b = load_reference()
    cov = np.array([[19000.0, 5100.0, 2300.0], [5100.0, 1400.0, 630.0], [2300.0, 630.0, 3000.0]])
    ko = identifiability_kO(b, cov, 36.4, n_pairs=200)
    assert ko["sets"]["pair BO, CC"]["rank"] == 2 and ko["sets"]["pair BO, CC"]["condition_number"] is None
    assert "κ +1 % reads as +0.42 nut steps" in ko["sets"]["pair BO, CC"]["unseen"]
    full = ko["sets"]["pair AO, BO, CC"]
    assert full["rank"] == 3 and full["sd_kappa_unit"] == pytest.approx(full["sd_kappa_one_pair"] / np.sqrt(200))
    assert ko["commissioned"]["sd_steps"] == pytest.approx(np.sqrt(2) * ko["commissioned"]["sd_steps_kappa_known"])


def test_the_pairs_only_study_reuses_the_pair_fits_and_writes_the_three_protocols(study, tmp_path):
    """`hvcb study classify-pairs` on the quick study's cached pair fits (no fit is redone)."""
    import shutil

    from service.studies import classify_pair_run

    out, res = study
    for f in out.glob("dataset-*.npz"):
        shutil.copy(f, tmp_path)
    before = sorted(p.name for p in tmp_path.glob("dataset-*.npz"))
    got = classify_pair_run.run(tmp_path, quick=True, methods=["proposed", "svm"])
    assert sorted(p.name for p in tmp_path.glob("dataset-*.npz")) == before  # no new fit
    assert got["pairs_only"] and set(got["protocols"]) == {"cv5_pair", "cross_unit_pair",
                                                           "cross_unit_pair_commissioned"}
    for p in ("cv5_pair", "cross_unit_pair", "cross_unit_pair_commissioned"):
        assert got["protocols"][p]["proposed"] == pytest.approx(res["protocols"][p]["proposed"])
    assert got["ceiling"]["single_opening_source"].startswith("the openings of the pair set")
    md = (tmp_path / "classify.md").read_text()
    assert "identifiability with the unit's spring rate free" in md and "kO from the unit's own AO·BC" in md
    data = json.loads((tmp_path / "classify.json").read_text())
    assert data["identifiability"]["kO_free"]["sets"]["pair BO, CC"]["condition_number"] is None
