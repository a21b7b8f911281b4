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
        assert set(a["parameter_bias"]) == {"AC", "BC", "CC"}


def test_contact_wipe_named_jointly(wipe):
    assert wipe["status"] == "named"
    assert wipe["effects"] == ["contact_wipe"]
    assert wipe["answer"] == "contact_wipe" and wipe["answer_probability"] >= 0.9
    assert wipe["answers"]["contact_wipe"] == wipe["answer_probability"]
    assert wipe["gap"]["after_rms_rad"] < wipe["gap"]["before_rms_rad"]
    touch = {w["phase"]: w for w in wipe["where"]}["contact_touch"]
    assert touch["gap_after"] < touch["gap_before"]


def test_healthy_group_is_none(healthy):
    assert healthy["status"] == "none"
    assert healthy["effects"] == []
    assert healthy["probabilities"]["none"] == max(healthy["probabilities"].values())


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
