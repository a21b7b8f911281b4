"""The ``[limits]`` table of a breaker file: maintenance limits of fitted parameters.

A limit says at which value of a fitted mechanism parameter the breaker must be serviced. It is
either absolute, in the parameter's unit (``DO = { min = 30.0 }``), or relative to the breaker's
own temperature-compensated baseline (``DO = { min_change = -0.25 }``: 25 % below it). The
prognosis (service.prognosis) forecasts when the compensated value crosses it.
"""

from __future__ import annotations

import math
from pydantic import BaseModel, ConfigDict, Field, RootModel, field_validator, model_validator

from .mechanics.breaker import TABLE2_RANGES

# The fitted parameters a limit may name: the search ranges' parameters plus the puffer damping
# CO (fitted for an [unknown_design] breaker).
LIMITABLE = tuple(TABLE2_RANGES) + ("CO",)
# ... and the vibration's trip-latch time [s] (service.vibration; [vibration] latch_time_max_ms in ms)
LIMITABLE += ("latch_time_s",)
# A relative change beyond +-100 % is not a maintenance limit but a different breaker.
MAX_RELATIVE_CHANGE = 1.0


class ParameterLimit(BaseModel):
    """One parameter's limit: at most one lower and one upper bound.

    min, max : absolute bound [the parameter's unit, e.g. DO s^-1, BO s^-2]
    min_change, max_change : bound relative to the compensated baseline [-], e.g. -0.25
    """

    model_config = ConfigDict(extra="forbid", frozen=True)
    min: float | None = Field(None, gt=0.0, allow_inf_nan=False)
    max: float | None = Field(None, gt=0.0, allow_inf_nan=False)
    min_change: float | None = Field(None, gt=-MAX_RELATIVE_CHANGE, lt=0.0, allow_inf_nan=False)
    max_change: float | None = Field(None, gt=0.0, le=MAX_RELATIVE_CHANGE, allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _table(cls, data):
        if not isinstance(data, dict):
            raise ValueError(f"must be a table such as {{ min = 30.0 }} or {{ min_change = -0.25 }}, got {data!r}")
        return data

    @model_validator(mode="after")
    def _one_per_side(self):
        if self.min is not None and self.min_change is not None:
            raise ValueError("give min or min_change, not both")
        if self.max is not None and self.max_change is not None:
            raise ValueError("give max or max_change, not both")
        if all(v is None for v in (self.min, self.max, self.min_change, self.max_change)):
            raise ValueError("needs a bound: min, max, min_change or max_change")
        if self.min is not None and self.max is not None and not self.min < self.max:
            raise ValueError(f"min {self.min:g} must be below max {self.max:g}")
        return self

    def bounds(self, baseline: float) -> list[tuple[str, float]]:
        """The bounds as ("falling" | "rising", value [unit]) for a compensated ``baseline``."""
        if not math.isfinite(baseline) or baseline <= 0:
            raise ValueError(f"baseline must be a positive finite value, got {baseline!r}")
        out = []
        if self.min is not None or self.min_change is not None:
            out.append(("falling", self.min if self.min is not None else baseline * (1.0 + self.min_change)))
        if self.max is not None or self.max_change is not None:
            out.append(("rising", self.max if self.max is not None else baseline * (1.0 + self.max_change)))
        return out

    def words(self, unit: str = "") -> str:
        """The limit in words: "25 % below the baseline", "10 % below or above the baseline",
        "at least 30 s⁻¹", "at most 50 s⁻¹ or 20 % above the baseline"."""
        def pct(x: float) -> str:
            return f"{abs(x) * 100:.3g} %"

        def absolute(x: float) -> str:
            return f"{x:.4g} {unit}".strip()

        if self.min_change is not None and self.max_change is not None and self.min_change == -self.max_change:
            return f"{pct(self.min_change)} below or above the baseline"
        parts = []
        if self.min is not None:
            parts.append(f"at least {absolute(self.min)}")
        if self.min_change is not None:
            parts.append(f"{pct(self.min_change)} below the baseline")
        if self.max is not None:
            parts.append(f"at most {absolute(self.max)}")
        if self.max_change is not None:
            parts.append(f"{pct(self.max_change)} above the baseline")
        return " or ".join(parts)

    def describe(self) -> str:
        """The limit as written, e.g. ``min_change = -0.25``."""
        return ", ".join(f"{k} = {v:g}" for k, v in self.model_dump(exclude_none=True).items())


class Limits(RootModel[dict[str, ParameterLimit]]):
    """The ``[limits]`` table: parameter name -> its limit."""

    root: dict[str, ParameterLimit] = Field(default_factory=dict)

    @field_validator("root")
    @classmethod
    def _known(cls, v):
        for name in v:
            if name not in LIMITABLE:
                raise ValueError(f"unknown parameter {name!r} (known: {', '.join(LIMITABLE)})")
        return v

    def items(self):
        return self.root.items()

    def __bool__(self) -> bool:
        return bool(self.root)



# The travel characteristics a breaker analyser reports (service.mechanics.characteristics) and
# their SI units: the keys a [characteristic_limits] table may name.
CHARACTERISTIC_UNITS = {"operating_time_s": "s", "average_speed_rad_s": "rad/s", "max_travel_rad": "rad",
                        "overtravel_rad": "rad", "rebound_rad": "rad", "damping_time_s": "s"}


class CharacteristicLimit(BaseModel):
    """The accepted range of one travel characteristic, as a manufacturer's test sheet gives it.

    min, max : bounds in the characteristic's SI unit (s, rad/s, rad), e.g. operating time
    ``{ min = 0.009, max = 0.014 }``
    """

    model_config = ConfigDict(extra="forbid", frozen=True)
    min: float | None = Field(None, ge=0.0, allow_inf_nan=False)
    max: float | None = Field(None, gt=0.0, allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _table(cls, data):
        if not isinstance(data, dict):
            raise ValueError(f"must be a table such as {{ min = 0.009, max = 0.014 }}, got {data!r}")
        return data

    @model_validator(mode="after")
    def _bounds(self):
        if self.min is None and self.max is None:
            raise ValueError("needs a bound: min or max")
        if self.min is not None and self.max is not None and not self.min < self.max:
            raise ValueError(f"min {self.min:g} must be below max {self.max:g}")
        return self


def _known_characteristics(v: dict) -> dict:
    for name in v:
        if name not in CHARACTERISTIC_UNITS:
            raise ValueError(f"unknown characteristic {name!r} (known: {', '.join(CHARACTERISTIC_UNITS)})")
    return v


class CharacteristicLimits(BaseModel):
    """The ``[characteristic_limits]`` table: per operation (``open``, ``close``) the accepted
    range of each travel characteristic; the condition report reads them as pass or fail."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    open: dict[str, CharacteristicLimit] = Field(default_factory=dict)
    close: dict[str, CharacteristicLimit] = Field(default_factory=dict)

    @field_validator("open", "close")
    @classmethod
    def _known(cls, v):
        return _known_characteristics(v)
