"""The warm fit's faster paths give what the slower ones gave (issue 56 item 3): the closing's
settled-rest check in closed form decides as np.polyfit's line and its covariance did, and the
vibration read's band-passed prefix is the whole channel's (the filter is causal)."""

from __future__ import annotations

import numpy as np
import pytest

from service.estimation.window import END_FIT_S, _settled
from service.vibration.events import band, detect_events, effective_dof, effective_dofs

FS = 128_000.0


def _polyfit_settled(y, fs):
    if y.size < END_FIT_S * fs or y.size < 8:
        return False
    coef, cov = np.polyfit(np.arange(y.size) / fs, y, 1, cov=True)
    return bool(coef[0] <= 3.0 * np.sqrt(max(cov[0, 0], 0.0)))


def test_the_settled_check_decides_as_polyfit_did():
    rng = np.random.default_rng(56)
    decided = set()
    for _ in range(300):
        n = int(rng.integers(400, 30_000))
        trend = rng.choice([0.0, 2e-5, 1e-4, 1e-3, -1e-3])
        y = 1.0 + rng.normal(0, 1e-3, n) + trend * np.arange(n) / n * rng.uniform(0, 3)
        want = _polyfit_settled(y, FS)
        assert _settled(y, 0, FS) == want
        decided.add(want)
    assert decided == {True, False}  # both answers were exercised


def test_the_banded_prefix_is_the_whole_channels():
    rng = np.random.default_rng(3)
    x = rng.normal(0, 1.0, 20_000)
    x[9_000:9_050] += 40 * np.sin(np.arange(50) / 2)
    whole = band(x, FS)
    for k in (500, 9_100, 15_000):
        assert np.allclose(band(x[:k], FS), whole[:k], rtol=0, atol=1e-12)


def test_the_read_hands_back_the_banded_channel_it_read():
    rng = np.random.default_rng(4)
    x = rng.normal(0, 0.6, 20_480)
    t_motion = 0.02
    i = int((t_motion - 1.2e-3) * FS)
    x[i:i + 60] += 30 * np.exp(-np.arange(60) / 20) * np.sin(np.arange(60))
    read = detect_events(x, FS, t_motion, "open", t_end_s=0.077, read_span_s=0.07)
    assert read.latch_time_s == pytest.approx(1.2e-3, abs=0.1e-3)
    assert read.banded is not None and read.banded.size >= int((t_motion + 0.07) * FS)
    assert np.allclose(read.banded, band(x, FS)[:read.banded.size], atol=1e-9)


def _one_dof(ref, n):
    """The single-n formula as it was written before the shared autocorrelation."""
    r = ref - ref.mean()
    var = float(np.sum(r * r)) / r.size
    lags = np.arange(1, min(n, r.size // 4))
    acf = np.array([np.sum(r[:-k] * r[k:]) for k in lags]) / (r.size * var)
    return float(n / (1.0 + 2.0 * np.sum((1.0 - lags / n) * acf**2)))


def test_several_effective_dofs_from_one_autocorrelation_are_each_the_single_one():
    rng = np.random.default_rng(5)
    ref = np.convolve(rng.standard_normal(3005), np.ones(5) / 5, "valid")
    assert effective_dofs(ref, (32, ref.size // 4)) == pytest.approx(
        [_one_dof(ref, 32), _one_dof(ref, ref.size // 4)], rel=1e-9)
    assert effective_dof(ref, 32) == pytest.approx(_one_dof(ref, 32), rel=1e-9)
