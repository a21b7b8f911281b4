"""The coarser RK4 grid (``data.JAC_DT_S``, one step per block) against the curves' finer one
(``data.CURVE_DT_S``): for the reduced opening and the smooth families it is used on, it changes
no state column by more than the finite difference's own truncation error does (its change
between the step h and h/2), and their curves by less than what would move χ² by 0.01; the
families it would move more keep the finer grid."""

import numpy as np
import pytest

from service.diagnosis.data import (
    BLOCK_S,
    CURVE_DT_S,
    JAC_DT_S,
    WindowData,
    design_state,
    fd_steps,
    model_curve,
    state_columns,
)
from service.diagnosis.hypotheses import family_starts
from service.diagnosis.data import JAC_STEP
from service.mechanics.effects import EFFECT_NAMES, OPERATIONS


def _window(breaker):
    t = np.arange(0.0, 0.05, BLOCK_S) + 0.5 * BLOCK_S
    return WindowData(t, np.zeros_like(t), np.full(t.size, 16.0), 1.5e-3, 0.0,
                      float(breaker.design_parameters()["DC"]), "test")


def _fine_columns(x, d, breaker, effects, scale):
    m0 = model_curve(x, d, breaker, "open", effects, dt_max=CURVE_DT_S)
    cols = []
    for j in range(x.size):
        h = (2e-6 if j == x.size - 1 else JAC_STEP * max(abs(x[j]), 1e-6)) * scale
        xp = x.copy()
        xp[j] += h
        cols.append((model_curve(xp, d, breaker, "open", effects, dt_max=CURVE_DT_S) - m0) * d.weight / h)
    return np.column_stack(cols)


@pytest.mark.parametrize("family", [None, "puffer_gas", "viscous_friction", "sensor_nonlinearity"])
def test_coarse_grid_columns_agree_within_the_finite_difference_error(breaker, family):
    d = _window(breaker)
    x = np.append(design_state(breaker, "open"), 1e-3)
    if family is None:
        effects = ()
    else:
        z = family_starts(family)[0]
        effects = [(family, 2.0 * float(z[0]), np.asarray(z[1:], float))]
    coarse = state_columns(x, d, breaker, "open", effects)      # the coarse grid for these
    fine, fine_half = _fine_columns(x, d, breaker, effects, 1.0), _fine_columns(x, d, breaker, effects, 0.5)
    size = np.max(np.abs(fine), axis=0)
    assert np.all(size > 0), "every state column moves the opening curve"
    grid_change = np.max(np.abs(coarse - fine), axis=0) / size
    fd_error = np.max(np.abs(fine_half - fine), axis=0) / size
    assert grid_change.max() <= fd_error.max(), (grid_change, fd_error)
    assert JAC_DT_S > CURVE_DT_S


def test_fd_steps_are_scipys_and_turn_back_at_a_bound():
    z = np.array([0.5, -3.0, 0.0, 0.99999])
    h = fd_steps(z, 1e-4, np.array([0.0, -5.0, 0.0, 0.0]), np.array([1.0, 5.0, 1.0, 1.0]))
    assert h[0] == pytest.approx(1e-4) and h[1] == pytest.approx(-3e-4) and h[2] == pytest.approx(1e-4)
    assert h[3] == pytest.approx(-1e-4)     # z + h would leave the upper bound: backwards


def _curve_change(breaker, family):
    """The largest change of an opening's curve [rad] between the two grids over the family's
    starts, each at its own strength and at the fits' strength bounds."""
    from service.diagnosis.hypotheses import strength_bounds

    d = _window(breaker)
    x = np.append(design_state(breaker, "open"), 1e-3)
    if family is None:
        cases = [()]
    else:
        cases = [[(family, st, np.asarray(z[1:], float))] for z in family_starts(family)
                 for st in {float(z[0]), *strength_bounds(family)} if st != 0.0]
    worst = 0.0
    for eff in cases:
        a = model_curve(x, d, breaker, "open", eff, dt_max=CURVE_DT_S)
        b = model_curve(x, d, breaker, "open", eff, dt_max=JAC_DT_S)
        if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
            worst = max(worst, float(np.max(np.abs(a - b))))
    return worst


# the change that would move χ² by 0.01 on 10⁴ blocks of a 1.5 mrad sensor at 16 samples a block
BOUND_RAD = 0.01 * (1.5e-3 / 4.0) / (2.0 * np.sqrt(1e4))


@pytest.mark.parametrize("family", [None] + [e for e in EFFECT_NAMES if "open" in OPERATIONS[e]])
def test_the_smooth_openings_are_the_ones_the_coarse_grid_leaves_unchanged(breaker, family):
    """The families integrated on the coarse grid (``SMOOTH_OPENING``) are exactly those whose
    curves it moves by less than BOUND_RAD; the others keep the finer step."""
    from service.diagnosis.data import SMOOTH_OPENING, curve_step

    change = _curve_change(breaker, family)
    smooth = family is None or family in SMOOTH_OPENING
    assert (change <= BOUND_RAD) == smooth, (family, change)
    step = curve_step("open", () if family is None else [(family, 1.0, None)])
    assert step == (JAC_DT_S if smooth else CURVE_DT_S)
