"""Effect families (issue 11): the prototype's own form is one member of each family, the shape
parameters change the curve within physical bounds, and the verdict does not hang on a 1e-6
perturbation of the reduced fit."""

import numpy as np
import pytest

from service.prototypes.a import (
    EFFECT_NAMES, OPERATIONS, REALISTIC, SHAPES, Effects, shape_bounds, shape_defaults, simulate_family,
    simulate_prototype_closing, simulate_prototype_opening,
)


def _sim(breaker, op, effect, strength, shape=None):
    p = breaker.design_parameters()
    t = np.arange(0, 0.06 if op == "open" else 0.11, 1 / 8000)
    return simulate_family(op, p, t, breaker=breaker, effect=effect, strength=strength, shape=shape,
                           dt_max=1 / 16000).theta


@pytest.mark.parametrize("effect", EFFECT_NAMES)
def test_default_shape_is_the_prototype(breaker, effect):
    """With its default shape a family reproduces the prototype's own equations exactly."""
    for op in OPERATIONS[effect]:
        p = breaker.design_parameters()
        t = np.arange(0, 0.06 if op == "open" else 0.11, 1 / 8000)
        eff = Effects.only(effect, REALISTIC[effect])
        simulate = simulate_prototype_opening if op == "open" else simulate_prototype_closing
        ref = simulate(p, t, breaker=breaker, effects=eff, method="fast", dt_max=1 / 16000).theta
        fam = _sim(breaker, op, effect, REALISTIC[effect], shape_defaults(effect))
        assert np.allclose(fam, ref, atol=1e-12, equal_nan=False)


@pytest.mark.parametrize("effect", EFFECT_NAMES)
def test_every_shape_parameter_changes_the_curve_within_its_bounds(breaker, effect):
    """Each shape parameter moved across its bounds changes the travel by more than the noise
    (1.5 mrad) somewhere, or at least measurably, and stays finite."""
    lo, hi = shape_bounds(effect)
    s = 2 * REALISTIC[effect]
    for j, spec in enumerate(SHAPES[effect]):
        a, b = shape_defaults(effect), shape_defaults(effect)
        a[j], b[j] = lo[j], hi[j]
        change = 0.0
        for op in OPERATIONS[effect]:  # a shape may act on one operation only (opening spring share)
            ca, cb = _sim(breaker, op, effect, s, a), _sim(breaker, op, effect, s, b)
            assert np.all(np.isfinite(ca)) and np.all(np.isfinite(cb)), spec[0]
            change = max(change, float(np.max(np.abs(ca - cb))))
        assert change > 1e-5, f"{effect}.{spec[0]} does not change the curve"
        assert lo[j] <= spec[1] <= hi[j]


def test_verdict_is_robust_to_a_tiny_change_of_the_reduced_fit(breaker, make_capture):
    """A 1e-6 relative change of the reduced fit's parameters leaves the verdict, and the named
    effect's strength to a few per cent, unchanged (multi-start fits, no knife-edge minimum)."""
    from service.diagnosis import diagnose
    from service.estimation import fit_capture

    cap = make_capture(breaker, "open", Effects(orifice_buffer=0.6), seed=171)

    def nudged(capture, brk, operation, seed=1):
        fr = fit_capture(capture, brk, operation, seed=seed)
        fr.parameters = {k: v * (1 + 1e-6) for k, v in fr.parameters.items()}
        return fr

    a = diagnose([cap], breaker, "open")
    b = diagnose([cap], breaker, "open", fitter=nudged)
    assert a["verdict"] == b["verdict"] == "orifice_buffer"
    assert b["how_far"]["strength"] == pytest.approx(a["how_far"]["strength"], rel=0.05)
    assert a["status"] in ("explained", "partly_explained")
    assert 0 < a["explained_fraction"] <= 1
