"""The breaker-level diagnosis end to end on prototype-A groups (seeds 101..199; the study uses others)."""

import json

import numpy as np
import pytest

from service.diagnosis import DiagnosisError, diagnose
from service.diagnosis.commands import _jsonable
from service.prototypes.a import groups as ga

CONTRACT = {"operation", "captures", "status", "effects", "probabilities", "rivals", "absorbed", "where",
            "gap", "reduced_parameters", "corrected_parameters", "next_measurement", "message"}


def _group(effects, op, n, seed):
    rng = np.random.default_rng(seed)
    unit = ga.make_unit(rng, effects=effects)
    return [ga.simulate_capture(unit, op, conditions=ga.draw_conditions(rng), rng=rng)[0] for _ in range(n)]


@pytest.fixture(scope="module")
def wipe(breaker):
    return diagnose(_group({"contact_wipe": 0.35}, "close", 3, 101), breaker, "close")


@pytest.fixture(scope="module")
def healthy(breaker):
    return diagnose(_group({}, "open", 3, 102), breaker, "open")


def test_contract(wipe):
    r = json.loads(json.dumps(wipe, default=_jsonable))
    assert CONTRACT <= set(r)
    assert r["captures"] == 3
    assert r["status"] in {"none", "named", "ambiguous", "unexplained"}
    assert {"none", "outside_catalogue", "contact_wipe"} <= set(r["probabilities"])
    assert sum(r["probabilities"].values()) == pytest.approx(1.0)
    assert [w["phase"] for w in r["where"]] == ["free_run", "cam_rise", "contact_touch", "end"]
    assert set(r["gap"]) >= {"before_rms_rad", "after_rms_rad", "noise_rad", "shrink"}
    assert len(r["reduced_parameters"]) == len(r["corrected_parameters"]) == 3
    assert set(r["reduced_parameters"][0]) == {"AC", "BC", "CC", "onset_delay_s"}
    for a in r["absorbed"]:
        assert set(a["bias"]) == {"AC", "BC", "CC"}
    assert r["answer_probability"] == r["probabilities"][r["answer"]]      # one number
    assert set(r["materiality"]) >= {"gap_sigma", "gap_sigma_interval", "effects"}
    assert {p["phase"] for p in r["discrepancy"]["phases"]} == {"free_run", "cam_rise", "contact_touch", "end"}


def test_contact_wipe_is_in_the_set_and_among_the_leaders(wipe):
    """The wipe is among the three most probable hypotheses and in the 90 % set; the group is
    not called healthy."""
    p = wipe["probabilities"]
    top3 = sorted(p, key=lambda k: -p[k])[:3]
    assert any("contact_wipe" in k.split("+") for k in top3)
    assert any("contact_wipe" in k.split("+") for k in wipe["set"])
    assert wipe["status"] != "none" and wipe["answer"] != "none"


@pytest.mark.xfail(strict=True, reason="issue 48: the shipped scorer (46 corpus groups, 2 wipe labels) answers "
                   "outside_catalogue 0.41 here, the wipe + sensor pair third (0.11): it is not named")
def test_contact_wipe_named_jointly(wipe):
    """The wipe alone, with its fitted strength near the generator's 0.35 (the single is refitted
    from the best pair's states, so a pair does not win on convergence alone)."""
    assert wipe["status"] == "named" and wipe["effects"] == ["contact_wipe"]
    assert wipe["answer"] == "contact_wipe" and wipe["answer_probability"] >= 0.9
    wipe_fit = {e["effect"]: e for e in wipe["materiality"]["effects"]}["contact_wipe"]
    assert wipe_fit["material"]
    assert wipe["probabilities"]["none"] < 1e-6
    assert wipe["gap"]["after_rms_rad"] < wipe["gap"]["before_rms_rad"]
    touch = {w["phase"]: w for w in wipe["where"]}["contact_touch"]
    assert touch["gap_after"] < touch["gap_before"]


@pytest.mark.xfail(strict=True, reason="issue 36/54: the exact refit of the wipe is path-dependent: 0.46 on the former "
                   "code (chi2 1097 on 1005 blocks, the truth's ~1013), 0.28 with the evidence's fit reused by the report "
                   "(issue 54): 20-32 % off the generator's 0.35, outside its stated interval; not solved this round")
def test_contact_wipe_strength(wipe):
    """The wipe's fitted strength near the generator's 0.35 (within 5 %: the unit's ±3 %
    tolerances trade against the strength) and inside its stated 95 % interval."""
    wipe_fit = {e["effect"]: e for e in wipe["materiality"]["effects"]}["contact_wipe"]
    assert abs(wipe_fit["strength"] - 0.35) < 0.05 * 0.35
    lo, hi = wipe_fit["strength_interval"]
    assert lo <= 0.35 <= hi


def test_healthy_group_is_none(healthy):
    """A healthy group is ``none``: decided by the test of the reduced model's residual against
    the noise (``none_test``), before any scorer; the set is ``none`` alone."""
    assert healthy["status"] == "none" and healthy["answer"] == "none"
    assert healthy["effects"] == [] and healthy["set"] == ["none"]
    assert healthy["none_test"]["none"] and healthy["none_test"]["p_value"] >= healthy["none_test"]["level"]


def test_bad_input_in_words(breaker):
    with pytest.raises(DiagnosisError, match="operation must be"):
        diagnose([], breaker, "sideways")
    with pytest.raises(DiagnosisError, match="no capture"):
        diagnose([], breaker, "open")
    with pytest.raises(DiagnosisError, match="unknown effect"):
        diagnose(_group({}, "open", 1, 103), breaker, "open", effects=["gremlins"])
    cap = _group({}, "open", 1, 104)[0]
    from dataclasses import replace
    half = replace(cap, travel=np.asarray(cap.travel) * 0.5)
    with pytest.raises(DiagnosisError, match="stroke"):
        diagnose([half], breaker, "open")


@pytest.fixture(scope="module")
def analyser_5ks(tmp_path_factory):
    """Four openings of 5 kS/s close-open analyser records (the reduced model's curve, no effect)."""
    from drivers.capture_file import read_capture
    from service.acquisition.capture_file import breaker_reading
    from service.breaker_file import load_breaker
    from tests.analyser.export_gen import Spec, write_export
    from tests.conftest import REPO

    from service.estimation.record import operation_capture

    b = load_breaker(REPO / "config/breakers/generic-analyser.toml")
    tmp_path = tmp_path_factory.mktemp("analyser")
    caps = []
    for seed in (1, 2, 3, 4):       # four records of one breaker (one record alone is weak evidence)
        path = tmp_path / f"rec{seed}.csv"
        write_export(path, Spec(rate=5_000, seed=seed))
        caps.append(operation_capture(read_capture(path, **breaker_reading(b)), b, "open")[0])
    return diagnose(caps, b, "open", next_measurements=False)


def test_a_5ks_analyser_record_is_diagnosed(analyser_5ks):
    """Blocks are a time (125 µs), not 16 samples: an opening of a 5 kS/s close-open analyser
    record is diagnosed, not refused for its length, and found healthy."""
    r = analyser_5ks
    assert r["noise_model"]["samples_per_block"] == 1.0
    assert r["blocks"] > 4 * 100
    assert r["status"] == "none" and r["answer"] == "none" and r["effects"] == []


@pytest.mark.xfail(strict=True, reason="issue 54: none is decided by the none test (p-value, not a probability); "
                   "the answer's probability shown is the shipped scorer's P(none), 0.45 on these records")
def test_a_5ks_analyser_record_none_is_stated_at_090(analyser_5ks):
    assert analyser_5ks["answer_probability"] >= 0.9


def test_a_gap_of_twice_the_noise_is_never_none(breaker):
    """A smooth gap the catalogue does not hold (a 2 ms sensor-lag step response… here a bump of
    the reading over 6 ms at mid-stroke, 3 mrad = 2σ): never ``none``, and P(none) ≤ 0.01."""
    from dataclasses import replace

    caps = []
    for cap in _group({}, "open", 3, 105):
        t = np.asarray(cap.t)
        t_mid = t[int(np.argmax(np.asarray(cap.travel) > 0.5 * breaker.stroke))]
        bump = 3e-3 * np.exp(-0.5 * ((t - t_mid) / 3e-3) ** 2)
        caps.append(replace(cap, travel=np.asarray(cap.travel) + bump))
    r = diagnose(caps, breaker, "open", next_measurements=False)
    assert r["gap"]["before_rms_rad"] >= 1.0 * r["gap"]["noise_rad"]
    assert r["status"] != "none" and r["answer"] != "none"
    assert r["probabilities"]["none"] <= 0.01
    assert not r["none_test"]["none"]
