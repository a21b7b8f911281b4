"""The latest operation judged against the breaker file's limits, as an analyser's report reads:
each travel characteristic against its ``[characteristic_limits]`` range, each fitted parameter
against its ``[limits]`` maintenance limit. Pure: numbers in, rows out.
"""

from __future__ import annotations

from dataclasses import dataclass

from service.breaker_limits import (
    CHARACTERISTIC_UNITS,
    CharacteristicLimit,
    ParameterLimit,
)
from service.display import finite as _finite

# How a characteristic is shown: label, display unit, factor from its SI unit.
CHARACTERISTIC_DISPLAY = {"operating_time_s": ("operating time", "ms", 1e3),
                          "average_speed_rad_s": ("average speed", "rad/s", 1.0),
                          "max_travel_rad": ("maximum travel", "mrad", 1e3),
                          "overtravel_rad": ("overtravel", "mrad", 1e3),
                          "rebound_rad": ("rebound", "mrad", 1e3),
                          "damping_time_s": ("damping time", "ms", 1e3)}

PASS, FAIL, NO_LIMIT, NOT_MEASURED, NO_BASELINE = "PASS", "FAIL", "no limit", "not measured", "no baseline yet"


@dataclass(frozen=True)
class Verdict:
    """One row of the results table: ``value`` and the bounds in ``unit`` (None: none)."""

    name: str
    label: str
    unit: str
    value: float | None
    low: float | None
    high: float | None
    result: str  # PASS | FAIL | no limit | not measured | no baseline yet

    @property
    def limit_text(self) -> str:
        from service.display import compact

        if self.low is not None and self.high is not None:
            return f"{compact(self.low)} to {compact(self.high)}"
        if self.low is not None:
            return f"≥ {compact(self.low)}"
        if self.high is not None:
            return f"≤ {compact(self.high)}"
        return "—"




def _judge(value: float | None, low: float | None, high: float | None) -> str:
    if low is None and high is None:
        return NO_LIMIT
    if value is None:
        return NOT_MEASURED
    return FAIL if (low is not None and value < low) or (high is not None and value > high) else PASS


def characteristic_verdicts(characteristics: dict | None, limits: dict[str, CharacteristicLimit]) -> list[Verdict]:
    """Every characteristic of an operation (SI, as stored) against its range, in display units."""
    chars = characteristics or {}
    out = []
    for key in CHARACTERISTIC_UNITS:
        label, unit, f = CHARACTERISTIC_DISPLAY[key]
        v = _finite(chars.get(key))
        lim = limits.get(key)
        low = lim.min * f if lim is not None and lim.min is not None else None
        high = lim.max * f if lim is not None and lim.max is not None else None
        shown = None if v is None else v * f
        out.append(Verdict(key, label, unit, shown, low, high, _judge(shown, low, high)))
    return out


def parameter_verdicts(parameters: dict | None, names, limits: dict[str, ParameterLimit],
                       baselines: dict[str, float | None], units: dict[str, str]) -> list[Verdict]:
    """Each fitted parameter of ``names`` against its maintenance limit; a relative limit needs
    the parameter's compensated baseline (``baselines``), else "no baseline yet"."""
    params = parameters or {}
    out = []
    for name in names:
        v = _finite(params.get(name))
        lim = limits.get(name)
        low = high = None
        result = None
        if lim is not None:
            base = _finite(baselines.get(name))
            relative = lim.min_change is not None or lim.max_change is not None
            if relative and (base is None or base <= 0):
                result = NO_BASELINE
                low, high = lim.min, lim.max
            else:
                for side, bound in lim.bounds(base if base is not None and base > 0 else 1.0):
                    if side == "falling":
                        low = bound
                    else:
                        high = bound
        out.append(Verdict(name, name, units.get(name, ""), v, low, high, result or _judge(v, low, high)))
    return out


def overall(verdicts) -> str:
    """FAIL if any row fails, PASS if at least one passes and none fails, else "no limit"."""
    results = {v.result for v in verdicts}
    return FAIL if FAIL in results else PASS if PASS in results else NO_LIMIT
