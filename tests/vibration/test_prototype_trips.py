"""The trip strikes in the prototypes: B wired to the blind generator (its physics untouched, the
capture unchanged without it), and the demo's history with a latch that sticks more each opening."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from service.api.demo import DemoScript, history
from service.prototypes.b.capture import simulate_capture
from service.vibration import detect_events


def test_prototype_b_with_the_blind_strike_and_without_it():
    plain, truth = simulate_capture("open", rng=np.random.default_rng(12))
    again, _ = simulate_capture("open", rng=np.random.default_rng(12), trip=None)
    assert np.array_equal(plain.vibration, again.vibration) and "latch_time_s" not in truth
    tripped, t2 = simulate_capture("open", rng=np.random.default_rng(12),
                                   trip={"latch_time_s": 3.0e-3, "strike_g": 40.0, "seed": 1})
    assert t2["latch_time_s"] == 3.0e-3 and t2["t_strike_s"] == pytest.approx(t2["t_motion_s"] - 3.0e-3)
    i_strike = int(t2["t_strike_s"] * tripped.sample_rate)
    assert np.array_equal(tripped.vibration[:i_strike], plain.vibration[:i_strike])  # nothing before the strike
    assert np.array_equal(tripped.travel, plain.travel)  # the physics untouched
    r = detect_events(tripped.vibration, tripped.sample_rate, t2["t_motion_s"], "open",
                      t_end_s=t2["t_end_of_stroke_s"], limits=tripped.vibration_limits)
    assert r.latch_time_s == pytest.approx(3.0e-3, abs=0.1e-3)


def test_demo_latch_sticks_more_each_opening(breaker):
    script = DemoScript(healthy_ops=100, total_ops=6, close_every=100, latch_stick_from=3,
                        latch_stick_per_op=0.3e-3, effects={"open": {}, "close": {}})
    latches = []
    for i, kind, cap in itertools.islice(history(breaker, script), 6):
        r = detect_events(cap.vibration, cap.sample_rate, 0.02, "open", limits=cap.vibration_limits)
        latches.append(r.latch_time_s)
    assert all(v is not None for v in latches)
    assert max(latches[:3]) < 1.4e-3  # healthy: 1.2 ms
    assert latches[3] < latches[4] < latches[5] and latches[5] == pytest.approx(1.2e-3 + 0.9e-3, abs=0.15e-3)
