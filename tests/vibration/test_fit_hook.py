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
