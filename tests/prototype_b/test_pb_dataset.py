"""Prototype B captures and datasets: shape of a capture, sensor effects, COMTRADE output."""

import json
from collections import Counter

import numpy as np
import pytest

from service.acquisition.capture_file import read_capture
from service.prototypes.b import (EFFECTS, OPERATIONS, OUTSIDE, REALISTIC, simulate_capture,
                                           write_dataset)
from service.prototypes.b.dataset import dataset_plan, reference_mechanism
from service.prototypes.b.effects import apply_effect
from service.prototypes.b.laws import Laws
from service.prototypes.b.mechanism import Effects

LSB = np.pi / (2**16 - 1)


def test_catalogue_is_complete():
    assert len(EFFECTS) == 10 and set(OUTSIDE) >= {"sensor_lag"}
    for name in EFFECTS + OUTSIDE:
        assert OPERATIONS[name] and set(OPERATIONS[name]) <= {"open", "close"}
        assert REALISTIC[name]
    assert all("OUTSIDE" in REALISTIC[name] for name in OUTSIDE)


@pytest.mark.parametrize("operation", ["open", "close"])
def test_control_capture_looks_like_a_recording(operation):
    cap, truth = simulate_capture(operation, rng=np.random.default_rng(11))
    fs = cap.sample_rate
    assert fs == 128000
    t = cap.t
    rest = t < truth["t_shock_s"]
    start = 0.0 if operation == "open" else 1.0
    assert 0.018 < truth["t_motion_s"] < 0.022
    assert np.std(cap.travel[rest]) == pytest.approx(1.5e-3, rel=0.2)
    assert np.mean(cap.travel[rest]) == pytest.approx(start, abs=1e-3)
    shock = (t >= truth["t_shock_s"]) & (t < truth["t_motion_s"])
    assert np.max(np.abs(cap.vibration[shock])) > 50.0          # the latch-release shock
    assert np.max(np.abs(cap.vibration[t < truth["t_shock_s"]])) < 10.0
    assert cap.duration == pytest.approx(truth["t_end_of_stroke_s"] + 0.03, abs=1e-4)
    tail = np.mean(cap.travel[t > truth["t_end_of_stroke_s"] + 0.01])
    if operation == "open":  # at rest on the buffer, a little past the open position
        assert 1.0 < tail < 1.12
    else:                    # held by the closing latch
        assert abs(tail) < 5e-3
    codes = cap.travel / LSB
    assert np.allclose(codes, np.round(codes), atol=1e-6)       # 16-bit coding
    c = truth["constants"]
    for name, nominal in (("kO", 130e3), ("TOf", 600.0), ("cb", 1500.0), ("kC", 90e3)):
        assert abs(c[name] / nominal - 1) <= 0.06
    assert truth["effect"] is None and truth["strength"] == 0.0


def test_constants_are_spread_per_capture():
    values = [simulate_capture("open", rng=np.random.default_rng(s))[1]["constants"]["kO"] for s in range(3)]
    assert len(set(values)) == 3


@pytest.mark.parametrize("operation,kind", [("open", "polynomial"), ("close", "eccentric")])
def test_sensor_nonlinearity_is_the_drawn_error(operation, kind):
    """Same physics, noise off: the capture differs from the control by the sensor error law."""
    seed = 5
    ctrl, _ = simulate_capture(operation, rng=np.random.default_rng(seed), spread=0.0, noise_rad=0.0)
    for s in range(20):
        cap, truth = simulate_capture(operation, "sensor_nonlinearity", 1.0, rng=np.random.default_rng(s),
                                      spread=0.0, noise_rad=0.0)
        if truth["shape"]["kind"] == kind:
            break
    assert truth["shape"]["kind"] == kind
    mech = reference_mechanism()
    laws = Laws(mech, apply_effect(Effects(), "sensor_nonlinearity", 1.0, truth["shape"]))
    n = min(cap.travel.size, ctrl.travel.size)
    expected = laws.sensor_error(ctrl.travel[:n])
    assert np.max(np.abs(expected)) > 2e-3
    assert np.max(np.abs(cap.travel[:n] - ctrl.travel[:n] - expected)) < 2.5 * LSB


def test_sensor_lag_delays_the_measured_travel():
    ctrl, truth = simulate_capture("open", rng=np.random.default_rng(2), spread=0.0, noise_rad=0.0)
    lag, lt = simulate_capture("open", "sensor_lag", 1.0, rng=np.random.default_rng(2), spread=0.0, noise_rad=0.0)
    tau = lt["shape"]["tau_s"]
    moving = (ctrl.t > truth["t_motion_s"] + 2e-3) & (ctrl.t < truth["t_motion_s"] + 0.02)
    d = ctrl.travel[moving] - lag.travel[moving]
    speed = np.gradient(ctrl.travel, 1 / ctrl.sample_rate)[moving]
    assert np.all(d > 0)
    # A first-order lag behind a ramp reads speed·τ low.
    assert np.median(d / speed) == pytest.approx(tau, rel=0.15)


def test_latch_ramp_delays_the_opening():
    ctrl, truth = simulate_capture("open", rng=np.random.default_rng(4), spread=0.0, noise_rad=0.0)
    late, _ = simulate_capture("open", "latch_ramp", 1.0, rng=np.random.default_rng(4), spread=0.0, noise_rad=0.0)
    assert np.argmax(late.travel >= 0.2) > np.argmax(ctrl.travel >= 0.2) + 20


def test_effect_on_the_wrong_operation_is_refused():
    with pytest.raises(ValueError, match="acts only on close"):
        simulate_capture("open", "contact_wipe", 1.0, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="unknown effect"):
        simulate_capture("open", "rust", 1.0, rng=np.random.default_rng(0))


def test_default_plan_counts():
    plan = dataset_plan(seed=1)
    counts = Counter((op, eff) for op, eff, _ in plan)
    assert counts[("open", None)] == 20 and counts[("close", None)] == 20
    for effect in EFFECTS:
        for op in OPERATIONS[effect]:
            assert counts[(op, effect)] == 10
    for effect in OUTSIDE:
        assert sum(counts[(op, effect)] for op in ("open", "close")) == 3
    assert len(plan) == 40 + 10 * sum(len(OPERATIONS[e]) for e in EFFECTS) + 3 * len(OUTSIDE)
    assert all(0.5 <= s <= 1.5 for _, e, s in plan if e is not None)
    assert plan == dataset_plan(seed=1) and plan != dataset_plan(seed=2)


def test_write_dataset_is_deterministic_and_readable(tmp_path):
    kw = dict(seed=9, per_effect=0, controls=2, outside=1)
    a = write_dataset(tmp_path / "a", **kw)
    b = write_dataset(tmp_path / "b", **kw)
    assert a == b and len(a) == 2 + len(OUTSIDE)
    assert json.loads((tmp_path / "a" / "manifest.json").read_text()) == a
    for entry in a:
        stem = entry["stem"]
        assert entry["effect"] is None or entry["effect"] in OUTSIDE
        for suffix in (".cfg", ".dat"):
            assert (tmp_path / "a" / f"{stem}{suffix}").read_bytes() == (tmp_path / "b" / f"{stem}{suffix}").read_bytes()
        cap = read_capture(tmp_path / "a" / f"{stem}.cfg")
        truth = entry["truth"]
        assert cap.sample_rate == 128000
        assert cap.duration == pytest.approx(truth["t_end_of_stroke_s"] + 0.03, abs=1e-4)
        start = 0.0 if entry["operation"] == "open" else 1.0
        assert np.mean(cap.travel[: int(0.015 * 128000)]) == pytest.approx(start, abs=2e-3)
        k = int(truth["t_shock_s"] * 128000)
        assert np.max(np.abs(cap.vibration[k:k + 200])) > 50.0
    c = write_dataset(tmp_path / "c", **{**kw, "seed": 10})
    assert [e["truth"]["constants"] for e in c] != [e["truth"]["constants"] for e in a]


def test_write_dataset_covers_effects(tmp_path):
    manifest = write_dataset(tmp_path, seed=3, per_effect=1, controls=0, outside=0)
    got = Counter((e["operation"], e["effect"]) for e in manifest)
    assert got == Counter({(op, e): 1 for e in EFFECTS for op in OPERATIONS[e]})
    assert len({e["stem"] for e in manifest}) == len(manifest)
    assert all(e["effect"] not in e["stem"] for e in manifest)


@pytest.mark.parametrize("operation", ["open", "close"])
def test_controls_fit_the_reduced_model_at_their_drawn_constants(breaker, operation):
    """A control is the reduced model at the drawn constants: the project's fit recovers them."""
    from service.estimation import fit_capture

    cap, truth = simulate_capture(operation, rng=np.random.default_rng(21))
    c = truth["constants"]
    AO = c["kO"] * c["rO"] ** 2 / c["J2"]
    if operation == "open":
        true = {"AO": AO, "BO": (c["kO"] * c["xO1"] * c["rO"] - c["TOf"]) / c["J2"],
                "DO": c["cb"] * c["rb"] ** 2 / c["J2"], "EO": c["kb"] * c["rb"] ** 2 / c["J2"]}
    else:
        true = {"AC": c["kC"] * c["rC"] * c["d"] / c["J1"], "BC": c["J2"] / c["J1"],
                "CC": (c["TCf"] + c["kO"] * c["xO0"] * c["rO"]) / c["J2"]}
    fit = fit_capture(cap, breaker, operation, dc=AO if operation == "close" else None)
    assert fit.rmse_rad < 1.1 * truth["noise_rad"]
    for name, value in true.items():
        assert fit.parameters[name] == pytest.approx(value, rel=0.01), name
