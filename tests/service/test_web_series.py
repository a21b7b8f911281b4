"""The web page's chart numbers: decimation keeps extremes, the trend cache extends exactly like a
rebuild, the phases and the drift trace match the detector."""

from __future__ import annotations

import json
from datetime import datetime, timedelta, timezone

import numpy as np
import pytest

from service.storage import crud
from service.storage.spool import Spool
from service.web.series import minmax_buckets, minmax_indices, spark_axis, sparkline
from service.web.trends import TrendStore

T0 = datetime(2026, 3, 1, tzinfo=timezone.utc)


def test_minmax_buckets_keep_a_one_sample_shock():
    rng = np.random.default_rng(3)
    t = np.arange(128_000) / 128_000.0
    y = rng.normal(0, 1.0, t.size)
    y[54_321] = 900.0   # a shock one sample wide
    y[99_999] = -700.0
    bt, lo, hi = minmax_buckets(t, y, 2000)
    assert len(bt) == len(lo) == len(hi) == 2000
    assert max(hi) == 900.0 and min(lo) == -700.0
    assert bt[0] == 0.0 and all(a < b for a, b in zip(bt, bt[1:]))
    # fewer samples than buckets: every sample is its own bucket
    bt, lo, hi = minmax_buckets(t[:10], y[:10], 2000)
    assert lo == hi == list(y[:10])


def test_minmax_indices_keep_extremes_and_the_latest_value():
    y = list(np.sin(np.linspace(0, 20, 10_000)))
    y[1234], y[8765] = 5.0, -5.0
    y[500] = None
    idx = minmax_indices(y, 100)
    assert 150 <= idx.size <= 201
    assert {1234, 8765, 9999} <= set(idx.tolist())
    assert list(idx) == sorted(set(idx.tolist()))
    assert list(minmax_indices([1.0, 2.0, 3.0], 100)) == [0, 1, 2]


def test_sparkline_spans_its_box():
    pts = [tuple(map(float, p.split(","))) for p in sparkline([1.0, 3.0, 2.0], width=100, height=20, pad=0).split()]
    assert pts == [(0.0, 20.0), (50.0, 0.0), (100.0, 10.0)]
    assert sparkline([1.0]) == ""


def test_sparkline_axis_keeps_noise_small_and_a_fall_whole():
    """BO's 1 % scatter stays within the middle tenth of a ±5 % box; a 42 % fall of DO sets its own range."""
    noise = [4800.0 * (1 + 0.01 * x) for x in (-1, 1, -0.5, 0.5, 0)]
    lo, hi = spark_axis(noise)
    assert hi - lo == pytest.approx(0.10 * 4800.0)
    ys = [float(p.split(",")[1]) for p in sparkline(noise, height=28, pad=2, axis=(lo, hi)).split()]
    assert max(ys) - min(ys) <= 0.2 * 24 + 1e-9  # 2 % of the value in a 10 % box: a fifth of the height
    fall = [40.0, 38.0, 30.0, 23.2]
    assert spark_axis(fall) == (23.2, 40.0)
    assert spark_axis([1.0]) is None


def _store_fits(env, n: int, start: int, *, do_scale=1.0, time_offset=timedelta(0)) -> None:
    rng = np.random.default_rng(start)
    with env.Session() as s, s.begin():
        for i in range(start, start + n):
            do = 39.5 * (1 + rng.normal(0, 0.004)) * do_scale
            params = {"AO": 3420.0, "BO": 4805.0 * (1 + rng.normal(0, 0.004)), "DO": do, "EO": 3950.0}
            op, _ = crud.create_operation(s, capture_key=Spool.new_key(), breaker_id=1, kind="open",
                                          occurred_at=T0 + timedelta(minutes=i) + time_offset, source="upload",
                                          capture_path="/nonexistent.cfg", capture_sha256="0" * 64, flags=[],
                                          sample_rate=128000.0, n_samples=100)
            result = {"parameters": params, "ci95": {k: [v * 0.995, v * 1.005] for k, v in params.items()},
                      "identifiable": True, "characteristics": {"operating_time_s": 0.011, "overtravel_rad": 0.02,
                                                                "average_speed_rad_s": 32.0, "rebound_rad": 0.001}}
            crud.store_fit_result(s, operation_id=op.id, result=result, curve=None)


def _body(store, env) -> dict:
    with env.Session() as s:
        return json.loads(store.body(s, crud.get_breaker(s, breaker_id=1), env.settings))


def test_trend_store_extends_exactly_like_a_rebuild(env):
    store = TrendStore(buckets=8)  # small: the decimation is exercised too
    _store_fits(env, 30, 0)
    first = _body(store, env)
    assert first["params"]["DO"]["n"] == 30 and first["params"]["DO"]["shown"] < 30
    assert 20 <= first["params"]["DO"]["drift"]["baseline"]["n"] <= 30  # the first 20 fits, and those learnt while quiet
    _store_fits(env, 12, 30, do_scale=0.9)  # a leak: the drift statistic climbs
    grown = _body(store, env)
    assert grown == _body(TrendStore(buckets=8), env)  # incremental == rebuilt from scratch
    assert grown["params"]["DO"]["n"] == 42
    assert max(s for s in grown["params"]["DO"]["drift"]["s"] if s is not None) >= 4.5
    assert len(grown["characteristics"]["operating_time_s"]["open"]["t"]) <= 17
    # a late fit of an older operation forces a rebuild in operation order
    _store_fits(env, 1, 100, time_offset=-timedelta(days=1))
    late = _body(store, env)
    assert late == _body(TrendStore(buckets=8), env)
    assert late["params"]["DO"]["t"][0] < grown["params"]["DO"]["t"][0]
