"""The latch time in the fit: ``characteristics.latch_time_s`` from the fit's own onset, and a bad
vibration channel that never fails the fit (the reason is in the result)."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

from drivers.synthetic import synthesize_capture
from service.estimation.fit import fit_capture
from service.prototypes.a.trip_strike import add_trip_strike
from service.vibration import FALSE_DETECTION_RATE


@pytest.fixture(scope="module")
def opening(breaker):
    cap, truth = synthesize_capture(breaker, "open", breaker.design_parameters(), rng=np.random.default_rng(8))
    return cap, truth


def test_fit_reads_the_latch_time_from_its_own_onset(breaker, opening):
    cap, truth = opening
    vib = add_trip_strike(cap.vibration, cap.sample_rate, truth.t_motion, 2.0e-3, np.random.default_rng(4))
    r = fit_capture(dataclasses.replace(cap, vibration=vib), breaker, "open")
    ch = r.characteristics
    assert ch["latch_time_s"] == pytest.approx(2.0e-3, abs=0.1e-3)
    assert "latch_time_reason" not in ch
    names = [e["name"] for e in ch["vibration_events"]]
    assert names[:2] == ["first_shock", "latch_release"]
    json.dumps(r.to_dict())  # the characteristics column takes it as it is


@pytest.mark.parametrize("vib,word", [(lambda v: np.zeros_like(v), "flat"),
                                      (lambda v: v[:-10], "samples but the travel"),
                                      (lambda v: np.full_like(v, np.nan), "NaN")])
def test_bad_vibration_never_fails_the_fit(breaker, opening, vib, word):
    cap, truth = opening
    r = fit_capture(dataclasses.replace(cap, vibration=vib(cap.vibration)), breaker, "open")
    assert r.characteristics["latch_time_s"] is None
    assert word in r.characteristics["latch_time_reason"]
    assert r.parameters["DO"] > 0  # the travel fit went on


def test_fit_json_carries_the_latch_time(samples_dir):
    proc = subprocess.run([sys.executable, "-m", "service.cli", "fit", str(samples_dir / "open-nominal.cfg"),
                           "--operation", "open", "--json"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    ch = json.loads(proc.stdout)["characteristics"]
    assert ch["latch_time_s"] == pytest.approx(0.4e-3, abs=0.05e-3)
    assert ch["vibration"]["false_detection_rate"] == pytest.approx(FALSE_DETECTION_RATE)


def test_a_nan_vibration_in_a_file_is_left_out_not_refused(breaker, opening):
    from drivers.capture_file import parse_csv

    cap, truth = opening
    vib = cap.vibration.copy()
    vib[500:520] = np.nan
    rows = "\n".join(f"{t:.9f},{y:.7f},{v:.4f}" for t, y, v in zip(cap.t, cap.travel, vib))
    read = parse_csv("t_s,travel_rad,vibration_g\n" + rows + "\n", source="site/op.csv")
    assert read.vibration is None and "NaN" in read.meta["vibration_unread"]
    r = fit_capture(read, breaker, "open")
    assert r.characteristics["latch_time_s"] is None
    assert "20 NaN or infinite samples" in r.characteristics["latch_time_reason"]


@pytest.mark.parametrize("name", ["open-nominal", "open-buffer-leak"])
def test_the_buffer_shock_is_where_the_fitted_travel_reaches_alpha0(breaker, samples_dir, name):
    from drivers.capture_file import read_capture

    ch = fit_capture(read_capture(samples_dir / f"{name}.cfg"), breaker, "open").characteristics
    # the independent simulator's buffer shock sits at the travel's buffer engagement, leak or not
    assert abs(ch["buffer_offset_s"]) < 0.1e-3 and ch["buffer_ratio"] == pytest.approx(1.0, abs=0.005)


def test_a_buffer_shock_the_travel_does_not_explain_moves_the_ratio(breaker, opening):
    from service.vibration.characteristics import buffer_offset

    cap, truth = opening
    def model(t):  # reaches α0 25 ms after motion
        return np.where(t > truth.t_motion + 0.025, 1.0, 0.0)
    n = cap.travel.size
    late = [{"name": "buffer_engagement", "t_s": 0.027, "peak_g": 200.0, "clipped": False}]
    got = buffer_offset(late, model, cap.sample_rate, truth.t_motion, alpha0=0.5, n=n)
    assert got["buffer_offset_s"] == pytest.approx(2e-3, abs=0.05e-3) and got["buffer_ratio"] == pytest.approx(1.08, abs=0.005)
    assert buffer_offset([], model, cap.sample_rate, truth.t_motion, 0.5, n=n)["buffer_offset_s"] is None
    # the coarse-then-fine search finds the very sample a search of every sample finds
    for k in (1, 15, 16, 17, n - 3):
        def step(t, k=k):
            return (np.asarray(t) * cap.sample_rate >= k - 1e-6).astype(float)
        exact = int(np.flatnonzero(step(cap.t) >= 0.5)[0])
        got = buffer_offset(late, step, cap.sample_rate, 0.0, alpha0=0.5, n=n)
        assert exact == k and 0.027 - got["buffer_offset_s"] == pytest.approx(k / cap.sample_rate, abs=1e-12)
    assert "never reaches" in buffer_offset(late, lambda t: np.zeros(np.size(t)), cap.sample_rate, 0.0,
                                            alpha0=0.5, n=n)["buffer_offset_reason"]
