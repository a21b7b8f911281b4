"""The pages' number formats: significant figures in plain notation, signed changes without
"−0.0 %", and one unit per fitted parameter from the nomenclature."""

import pytest

from service.mechanics.nomenclature import CLOSING, OPENING, UNITS
from service.web.render import significant, signed_change


@pytest.mark.parametrize("value,digits,text", [
    (3.7040639646872, 3, "3.70"), (4.566881308526698, 3, "4.57"), (3419.9357, 3, "3420"),
    (3419.9357, 4, "3420"), (40.257, 4, "40.26"), (0.00035063, 3, "0.000351"), (-12.345, 3, "−12.3"),
    (-0.0001, 1, "−0.0001"), (0.0, 3, "0"), (None, 3, "—"), (float("nan"), 3, "—"), ("x", 3, "—"),
])
def test_significant(value, digits, text):
    assert significant(value, digits) == text


@pytest.mark.parametrize("rel,text", [(-0.05, "−5.0 %"), (0.003, "+0.3 %"), (-0.0004, "0.0 %"),
                                      (0.0004, "0.0 %"), (-0.42, "−42.0 %"), (None, "—")])
def test_signed_change_never_shows_minus_zero(rel, text):
    assert signed_change(rel) == text


def test_every_fitted_parameter_has_a_unit():
    assert set(OPENING + CLOSING + ("CO", "DC")) <= set(UNITS)
    assert {UNITS[p] for p in ("AO", "BO", "EO", "AC", "CC", "DC")} == {"s⁻²"}
    assert UNITS["DO"] == UNITS["CO"] == "s⁻¹" and UNITS["BC"] == "–"


def test_machine_units_are_the_same_units_in_ascii():
    from service.mechanics.nomenclature import machine_unit

    assert [machine_unit(p) for p in ("AO", "DO", "BC")] == ["s^-2", "s^-1", "1"]
