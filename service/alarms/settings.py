"""Drift-detector settings: a pydantic model built from the ``[alarms]`` config section.

Thresholds are in units of the standardised deviation (dimensionless, "baseline sigmas"), so one
set of values serves every watched parameter whatever its unit. The decision thresholds h are
not set by hand: they follow from the target false-alarm rates through the CUSUM's average run
length (``service.alarms.design``), see docs/alarms.md. They are designed once per settings and
kept (``service.alarms.design_cache``), so loading the settings does not pay the design.
"""

from __future__ import annotations

import tomllib
from functools import cached_property
from types import MappingProxyType
from typing import Any, Literal, Mapping

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

# Which way a parameter may drift before it means a fault.
DIRECTIONS = ("falling", "rising", "both")

# DO falling = the buffer oil is leaking (less damping). BO either way = opening spring
# relaxation, a resistance change or a pre-compression change. latch_time_s rising = the trip
# latch sticks (dried grease, wear): read from the vibration (service.vibration), so a breaker
# whose captures carry none simply gives it no values (it never alarms and never blocks the status).
DEFAULT_WATCHED: Mapping[str, str] = MappingProxyType({"DO": "falling", "BO": "both", "latch_time_s": "rising"})
OFF = "off"
"""A per-breaker override's word for "not watched on this breaker" (``[alarms.breakers.NAME]``)."""

# Temperature dependence physics allows, relative to the parameter's value [1/K] (docs/alarms.md):
# DO is buffer damping, set by the oil's viscosity, which falls with temperature (mineral oils
# about -2 to -3 %/K at 20 C; an orifice damper depends on it less): -3 %/K .. 0.
# BO is the opening spring over the moving mass: steel's shear modulus changes by about
# -0.025 %/K; friction in the linkage may add either sign: -0.2 .. +0.2 %/K.
DEFAULT_TEMPERATURE_SLOPES: Mapping[str, tuple[float, float]] = MappingProxyType(
    {"DO": (-0.03, 0.0), "BO": (-0.002, 0.002)})


class DriftSettings(BaseModel):
    """Settings of the drift detector (see docs/alarms.md for the design).

    baseline_n : fits collected before monitoring starts [fits]
    baseline_max : the baseline keeps learning (while the statistic is quiet) up to this many
        fits, then freezes [fits]
    baseline_hard_max : ... or, while it has not yet spanned ``temperature_span_k``, up to this [fits]
    temperature_span_k : the temperature range the baseline must have seen before it freezes [K]
    k : CUSUM reference value (allowance per fit) = half the design shift [z]
    design_false_warnings_per_10k, design_false_alarms_per_10k : the in-control rates per breaker
        (all watched sides together) the thresholds are derived from [1 per 10 000 operations]
    z_cap : winsorisation of each fit's score: one fit adds at most z_cap - k [z]
    common_mode_z : the temperature slope's error is the same for every fit (a common-mode
        bias b_err (T - T_mean)); the CUSUM's reference absorbs it up to this many of its sds [-]
    clear_level, clear_count : the statistic must stay below clear_level [z] for clear_count
        consecutive fits to clear
    statistic_cap : upper bound of the CUSUM, so a repaired fault clears in bounded time [z]
    sd_floor_rel : lower bound of the baseline sd, relative to the baseline mean [-]
    screen_sigmas, screen_min_rel : a first-baseline fit further from the median than both
        screen_sigmas MAD-sigmas and screen_min_rel of the median is a gross outlier
    max_evidence_ops : operation ids kept as evidence of one excursion [ops]
    watched : parameter name -> "falling" | "rising" | "both"
    breakers : breaker name -> {parameter name -> "falling" | "rising" | "both" | "off"}: the
        watched set of one breaker differs (``for_breaker``); its thresholds are designed for
        its own sides, so its total false-alarm rate is the designed one too
    temperature_slopes : parameter name -> (lowest, highest) relative slope physics allows [1/K]
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    baseline_n: int = Field(20, ge=3)
    baseline_max: int = Field(200, ge=3)
    baseline_hard_max: int = Field(1000, ge=3)
    temperature_span_k: float = Field(30.0, ge=0, allow_inf_nan=False)
    k: float = Field(1.25, gt=0, allow_inf_nan=False)
    design_false_warnings_per_10k: float = Field(0.25, gt=0, allow_inf_nan=False)
    design_false_alarms_per_10k: float = Field(0.025, gt=0, allow_inf_nan=False)
    z_cap: float = Field(3.0, gt=0, allow_inf_nan=False)
    common_mode_z: float = Field(1.0, ge=0, allow_inf_nan=False)
    clear_level: float = Field(1.0, ge=0, allow_inf_nan=False)
    clear_count: int = Field(5, ge=1)
    statistic_cap: float = Field(10.0, gt=0, allow_inf_nan=False)
    sd_floor_rel: float = Field(0.002, gt=0, allow_inf_nan=False)
    screen_sigmas: float = Field(3.5, gt=0, allow_inf_nan=False)
    screen_min_rel: float = Field(0.05, ge=0, allow_inf_nan=False)
    max_evidence_ops: int = Field(100, ge=1)
    watched: dict[str, Literal["falling", "rising", "both"]] = Field(
        default_factory=lambda: dict(DEFAULT_WATCHED), min_length=1)
    temperature_slopes: dict[str, tuple[float, float]] = Field(
        default_factory=lambda: dict(DEFAULT_TEMPERATURE_SLOPES))
    breakers: dict[str, dict[str, Literal["falling", "rising", "both", "off"]]] = Field(default_factory=dict)

    @field_validator("breakers")
    @classmethod
    def _breakers(cls, v):
        for name, over in v.items():
            if not over:
                raise ValueError(f"[alarms.breakers.{name}] is empty: name a parameter and a direction or \"off\"")
        return v

    @field_validator("temperature_slopes")
    @classmethod
    def _slopes(cls, v):
        for name, (lo, hi) in v.items():
            if not lo <= hi or abs(lo) > 0.2 or abs(hi) > 0.2:
                raise ValueError(f"temperature slope range of {name} must be (lowest, highest) "
                                 f"with lowest <= highest, within +-0.2 per K, got ({lo}, {hi})")
        return v

    @model_validator(mode="after")
    def _consistent(self):
        if self.z_cap <= self.k:
            raise ValueError(f"z_cap ({self.z_cap}) must exceed k ({self.k})")
        if self.baseline_max < self.baseline_n:
            raise ValueError(f"baseline_max ({self.baseline_max}) must be at least baseline_n "
                             f"({self.baseline_n})")
        if self.baseline_hard_max < self.baseline_max:
            raise ValueError(f"baseline_hard_max ({self.baseline_hard_max}) must be at least "
                             f"baseline_max ({self.baseline_max})")
        if self.design_false_alarms_per_10k > self.design_false_warnings_per_10k:
            raise ValueError("design_false_alarms_per_10k must not exceed design_false_warnings_per_10k")
        for name in self.breakers:  # an override that leaves nothing watched is refused at load, not at a fit
            self.for_breaker(name)
        if not self.clear_level < self.h_warning <= self.h_alarm <= self.statistic_cap:
            raise ValueError(
                "the derived thresholds must satisfy clear_level < h_warning <= h_alarm <= "
                f"statistic_cap, got {self.clear_level} < {self.h_warning:.3f} <= "
                f"{self.h_alarm:.3f} <= {self.statistic_cap}")
        return self

    # -- derived thresholds ---------------------------------------------------------------------
    @property
    def sides(self) -> int:
        """One-sided CUSUMs run per breaker (a "both" parameter runs two)."""
        return sum(2 if d == "both" else 1 for d in self.watched.values())

    @cached_property
    def h_warning(self) -> float:
        """Warning threshold [z]: in-control ARL of one side = sides * 10^4 / design rate."""
        from service.alarms.design_cache import threshold

        return threshold(self.sides * 1e4 / self.design_false_warnings_per_10k, k=self.k, z_cap=self.z_cap)

    @cached_property
    def h_alarm(self) -> float:
        """Alarm threshold [z], from ``design_false_alarms_per_10k`` like ``h_warning``."""
        from service.alarms.design_cache import threshold

        return threshold(self.sides * 1e4 / self.design_false_alarms_per_10k, k=self.k, z_cap=self.z_cap)

    def for_breaker(self, name: str | None) -> "DriftSettings":
        """The settings of breaker ``name``: ``watched`` with its ``[alarms.breakers.NAME]``
        overrides applied ("off" removes a parameter), thresholds designed for its own number of
        sides. The same object when the breaker has no override. ValueError when the overrides
        leave nothing watched."""
        over = self.breakers.get(name) if name is not None else None
        if not over:
            return self
        if name not in self.per_breaker:  # designed once per breaker, not on every fit
            self.per_breaker[name] = self._with_overrides(name, over)
        return self.per_breaker[name]

    @cached_property
    def per_breaker(self) -> dict:
        """breaker name -> its ``for_breaker`` settings, built on first use."""
        return {}

    def _with_overrides(self, name: str, over: Mapping[str, str]) -> "DriftSettings":
        watched = {**self.watched, **over}
        watched = {p: d for p, d in watched.items() if d != OFF}
        if not watched:
            raise ValueError(f"[alarms.breakers.{name}] turns every watched parameter off: put the breaker "
                             "out of service instead (docs/alarms.md)")
        # validated anew (not model_copy): the thresholds are cached on the instance
        return type(self).model_validate({**self.model_dump(), "watched": watched, "breakers": {}})

    def direction(self, parameter: str) -> str:
        """The watched direction of ``parameter``; ValueError if it is not watched."""
        try:
            return self.watched[parameter]
        except KeyError:
            raise ValueError(f"parameter {parameter!r} is not watched for drift "
                             f"(watched: {', '.join(sorted(self.watched))})") from None

    def slope_range(self, parameter: str) -> tuple[float, float] | None:
        """Relative temperature slope range [1/K] of ``parameter``; None: not compensated."""
        return self.temperature_slopes.get(parameter)

    # -- construction ---------------------------------------------------------------------------
    @classmethod
    def from_mapping(cls, section: Mapping[str, Any], *, source: str = "[alarms]") -> "DriftSettings":
        """Build from a config section such as ``[alarms]`` in config/default.toml.

        Errors are one ValueError in words, naming each wrong setting; unknown keys are refused,
        so a typo cannot silently leave a default.
        """
        if not isinstance(section, Mapping):
            raise ValueError(f"{source} must be a table of settings, got {type(section).__name__}")
        try:
            return cls.model_validate(dict(section))
        except ValidationError as exc:
            raise ValueError(f"{source}: " + "; ".join(_words(e) for e in exc.errors())) from None

    @classmethod
    def from_toml(cls, text: str, *, source: str = "alarm settings") -> "DriftSettings":
        """Build from TOML text: either an ``[alarms]`` table or the bare keys."""
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{source} is not valid TOML: {exc}") from None
        return cls.from_mapping(data.get("alarms", data), source=source)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able copy, the inverse of ``from_mapping``."""
        out = self.model_dump()
        out["temperature_slopes"] = {k: list(v) for k, v in self.temperature_slopes.items()}
        return out


def _words(error: Mapping[str, Any]) -> str:
    where = ".".join(str(p) for p in error.get("loc", ())) or "alarm settings"
    kind, msg = error.get("type", ""), error.get("msg", "")
    if kind == "extra_forbidden":
        return f"unknown alarm setting {where}"
    if kind == "literal_error":
        return f"alarm direction {where} must be one of {', '.join(DIRECTIONS)}, got {error.get('input')!r}"
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    return f"{where}: {msg} (got {error.get('input')!r})" if where != "alarm settings" else msg
