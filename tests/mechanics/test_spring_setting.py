"""The spring setting from a close–open pair (service.mechanics.spring_setting): the inversion of
Eqs. 8 and 12, the spring rate's offset, the commissioning pair that removes it, and the stated
interval checked by simulation."""

from __future__ import annotations

import numpy as np
import pytest

from service.mechanics.spring_setting import (
    NUT_STEP_M,
    pair_reading,
    setting,
    step_nm,
    steps_per_kO,
)
from service.studies.condition_data import STEP_M


def forward(b, k: float, f: float, kappa: float = 1.0, J2: float | None = None):
    """(BO, BC, CC) of a unit with spring rate κ·kO at k nut steps and friction factor f."""
    J2 = b.J2 if J2 is None else J2
    kO = kappa * b.kO
    P = kO * k * NUT_STEP_M * b.rO
    BO = (kO * b.xO1 * b.rO + P - f * b.TOf) / J2
    CC = (f * b.TCf + kO * b.xO0 * b.rO + P) / J2
    return BO, J2 / b.J1, CC


def test_the_nut_step_is_the_studies_step():
    assert NUT_STEP_M == STEP_M


@pytest.mark.parametrize("k,f", [(0.0, 1.0), (2.0, 0.9), (-1.5, 1.1), (4.0, 1.05)])
def test_a_pair_reads_its_setting_and_friction_whatever_the_units_J2(breaker, k, f):
    for J2 in (breaker.J2, 1.03 * breaker.J2):  # BC carries J2: the torques over J1 are free of it
        r = pair_reading(breaker, *forward(breaker, k, f, J2=J2))
        assert r["steps"] == pytest.approx(k, abs=1e-9) and r["friction"] == pytest.approx(f, abs=1e-12)


def test_a_stiffer_spring_reads_as_more_steps_and_the_commissioning_pair_removes_it(breaker):
    assert steps_per_kO(breaker) / 100 == pytest.approx(0.4234, abs=1e-4)  # docs/pairs.md: 0.42 steps per 1 %
    kappa = 1.01
    r = pair_reading(breaker, *forward(breaker, 3.0, 0.95, kappa=kappa))
    assert r["steps"] - 3.0 == pytest.approx(steps_per_kO(breaker) * (kappa - 1) + 3.0 * (kappa - 1), abs=1e-6)
    ref = dict(pair_reading(breaker, *forward(breaker, 1.0, 1.02, kappa=kappa), sd={"BO": 1, "BC": 1e-4, "CC": 1}),
               known_steps=1.0)
    got = setting(dict(r, sd_steps=0.01), breaker, reference=ref)
    # the offset cancels; what is left is κ's change of the step size itself (1 % of 2 steps)
    assert got["steps"] == pytest.approx(3.0 + 2.0 * (kappa - 1), abs=1e-6) and got["kO_sd_steps"] == 0.0
    assert "commissioning pair" in got["basis"]
    alone = setting(dict(r, sd_steps=0.01), breaker)
    assert alone["kO_sd_steps"] == pytest.approx(0.03 / np.sqrt(3) * steps_per_kO(breaker))
    assert alone["ci95"][0] < 3.0 < alone["ci95"][1] and "not known" in alone["basis"]


def test_the_stated_sd_holds_in_a_simulation(breaker):
    """Fitted BO, BC, CC drawn about the truth with the stated sds: the reading's scatter
    matches its first-order sd, and its 95 % interval covers 95 %."""
    rng = np.random.default_rng(39)
    sd = {"BO": 30.0, "BC": 0.01, "CC": 60.0}
    BO, BC, CC = forward(breaker, 2.0, 1.0)
    steps, stated = [], None
    for _ in range(4000):
        r = pair_reading(breaker, BO + rng.normal(0, sd["BO"]), BC + rng.normal(0, sd["BC"]),
                         CC + rng.normal(0, sd["CC"]), sd=sd)
        steps.append(r["steps"])
        stated = r["sd_steps"]
    steps = np.array(steps)
    assert np.std(steps) == pytest.approx(stated, rel=0.05)
    assert 0.93 < np.mean(np.abs(steps - 2.0) <= 1.959964 * stated) < 0.97
    assert step_nm(breaker) == pytest.approx(36.4)
