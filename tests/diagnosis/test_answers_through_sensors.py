"""Answers on prototypes other than A, read through the sensor layers (issue 48 item 7): B, C and
D are simulators written apart from the diagnosis's own model, and the realistic and crank
transducers add zero, gain, bow, struck modes, coupling and play. These check the shipped scorer
and set on what they were built for, and can fail on a wrong answer."""

import numpy as np
import pytest

from service.diagnosis import diagnose


def _read(caps, kind, seed, breaker, operation):
    from service.prototypes import sensor, sensor_crank

    mod = {"realistic": sensor, "crank": sensor_crank}[kind]
    rng = np.random.default_rng(seed)
    unit = mod.draw_unit(rng)
    return [mod.apply(c, unit, rng, stroke=breaker.stroke, operation=operation) for c in caps]


def _b_group(effects, n, seed):
    from service.prototypes.b import groups as gb

    rng = np.random.default_rng(seed)
    unit = gb.make_unit(rng, effects=effects)
    return [gb.simulate_capture(unit, "open", conditions=gb.draw_conditions(rng), rng=rng)[0] for _ in range(n)]


def _healthy_group(proto, tmp_path, seed, n=3):
    """One healthy group of ``proto`` written by its own generator (the corpus's path)."""
    from service.studies.gap.runner import write_jobs

    jobs = write_jobs(tmp_path, proto, seed, {"per_effect": 0, "controls": 1, "two_effect": 0, "outside": 0,
                                             "captures_per_group": n})
    j = [x for x in jobs if not x["truth"] and not x["outside"]][0]
    return j, j["operation"]


@pytest.fixture(scope="module")
def b_buffer(breaker):
    caps = _read(_b_group({"orifice_buffer": 1.0}, 5, 4801), "realistic", 4802, breaker, "open")
    return diagnose(caps, breaker, "open", next_measurements=False)


@pytest.mark.xfail(strict=True, reason="issue 48: the shipped scorer (46 corpus groups, no orifice-buffer label) "
                   "answers sensor nonlinearity 0.53 here; the buffer is not among its first three")
def test_b_orifice_buffer_through_the_realistic_sensor(b_buffer):
    """A strong orifice buffer on B (not A's equations), read through the lever transducer: the
    gap is not called none, and the buffer is among the three most probable hypotheses and in the
    90 % set."""
    r = b_buffer
    ranked = sorted(r["probabilities"], key=lambda k: -r["probabilities"][k])
    assert r["status"] != "none" and "none" not in ranked[:1]
    assert any("orifice_buffer" in k.split("+") for k in ranked[:3])
    assert any("orifice_buffer" in k.split("+") for k in r["set"])
    assert len(r["set"]) == len(r["set_members"]) and all(m["probability"] > 0 for m in r["set_members"])


@pytest.mark.parametrize("proto,kind", [("d", "realistic"), ("c", "crank")])
def test_a_healthy_breaker_through_a_sensor_names_no_mechanism_effect(proto, kind, breaker, tmp_path):
    """A healthy unit of D (realistic sensor) and of C (crank sensor): its truth is ``none`` or
    the sensor's own nonlinearity, which the 90 % set holds; no mechanism effect is named."""
    from service.acquisition.capture_file import read_capture

    job, op = _healthy_group(proto, tmp_path, 4803)
    caps = [read_capture(str(tmp_path / proto / f"{s}.cfg"), travel_channel=breaker.channels["travel"],
                         vibration_channel=breaker.channels["vibration"]) for s in job["stems"]]
    r = diagnose(_read(caps, kind, 4804, breaker, op), breaker, op, next_measurements=False)
    assert {"none", "sensor_nonlinearity"} & set(r["set"])
    mechanism = set(r["effects"]) - {"sensor_nonlinearity"}
    assert not (r["status"] == "named" and mechanism)
