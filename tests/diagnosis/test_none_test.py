"""``none_test``: the nested F test of the reduced model's residual against the noise refuses
``none`` at its designed rate on pure noise, whatever the noise's scale, and refuses it on a
smooth gap of twice the block noise."""

from types import SimpleNamespace

import numpy as np
from scipy.stats import binomtest

from service.diagnosis.data import BLOCK_S
from service.diagnosis.none_test import LEVEL, none_test


def _windows(rng, gap=None, scale=1.0, n_caps=3, blocks=320, p=8):
    caps = []
    t = np.arange(blocks) * BLOCK_S
    for _ in range(n_caps):
        N = np.column_stack([np.ones(blocks), t, np.sin(40 * t), rng.normal(size=(blocks, p - 3))])
        Q, _ = np.linalg.qr(N)
        r = scale * rng.normal(size=blocks) + (0.0 if gap is None else gap(t))
        caps.append(SimpleNamespace(Q=Q, r=r, data=SimpleNamespace(t=t, weight=np.ones(blocks))))
    return SimpleNamespace(captures=caps)


def test_the_false_rate_is_the_designed_level_on_pure_noise():
    rng = np.random.default_rng(54)
    draws = 600
    refused = sum(not none_test(_windows(rng, scale=float(rng.uniform(0.5, 3.0)))).consistent for _ in range(draws))
    # the designed rate lies in the two-sided 99 % interval of the measured one
    ci = binomtest(refused, draws).proportion_ci(confidence_level=0.99)
    assert ci.low <= LEVEL <= ci.high, (refused, draws)


def test_p_values_are_uniform_on_pure_noise():
    rng = np.random.default_rng(7)
    p = np.array([none_test(_windows(rng)).p_value for _ in range(300)])
    from scipy.stats import kstest

    assert kstest(p, "uniform").pvalue > 0.001


def test_a_smooth_gap_of_twice_the_block_noise_refuses_none():
    rng = np.random.default_rng(3)
    bump = lambda t: 2.0 * np.exp(-0.5 * ((t - 0.02) / 3e-3) ** 2)   # 2 sigma over ~6 ms
    nt = none_test(_windows(rng, gap=bump))
    assert not nt.consistent and nt.p_value < LEVEL
    assert nt.df_gap > 0 and nt.df_noise > nt.df_gap
