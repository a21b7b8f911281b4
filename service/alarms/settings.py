"""Drift-detector settings: one frozen dataclass, built from the ``[alarms]`` config section.

All thresholds are in units of the standardised deviation z (dimensionless, "baseline sigmas"),
so one set of values serves every watched parameter whatever its physical unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from types import MappingProxyType
from typing import Any, Mapping

# Which way a parameter may drift before it means a fault.
DIRECTIONS = ("falling", "rising", "both")

# DO falling = the buffer oil is leaking (less damping). BO either way = opening spring
# relaxation, a resistance change or a pre-compression change.
DEFAULT_WATCHED: Mapping[str, str] = MappingProxyType({"DO": "falling", "BO": "both"})


@dataclass(frozen=True)
class DriftSettings:
    """Settings of the CUSUM drift detector (see docs/alarms.md for the design).

    baseline_n : int — good fits that form a breaker's baseline [fits]
    k : float — CUSUM reference value (allowance per fit) [z]
    h_warning : float — decision threshold of the warning level [z]
    h_alarm : float — decision threshold of the alarm level [z]
    clear_level : float — the statistic must stay below this to clear [z]
    clear_count : int — ... for this many consecutive fits [fits]
    z_cap : float — winsorisation of each fit's z: one fit adds at most z_cap - k [z]
    statistic_cap : float — upper bound of the CUSUM, so a repaired fault clears in bounded time [z]
    sd_floor_rel : float — lower bound of the baseline sd, relative to the baseline mean [-]
    screen_sigmas, screen_min_rel : float — a baseline fit further from the median than both
        screen_sigmas MAD-sigmas [z] and screen_min_rel of the median [-] is a gross outlier
        and is left out of the baseline
    max_evidence_ops : int — operation ids kept as evidence of one excursion [ops]
    watched : mapping parameter name -> "falling" | "rising" | "both"
    """

    baseline_n: int = 20
    k: float = 1.25
    h_warning: float = 3.0
    h_alarm: float = 4.5
    clear_level: float = 1.0
    clear_count: int = 5
    z_cap: float = 3.0
    statistic_cap: float = 10.0
    sd_floor_rel: float = 0.002
    screen_sigmas: float = 3.5
    screen_min_rel: float = 0.05
    max_evidence_ops: int = 100
    watched: Mapping[str, str] = field(default_factory=lambda: DEFAULT_WATCHED)

    def __post_init__(self) -> None:
        # Freeze the mapping so settings stay hashable-in-spirit and shareable between threads.
        object.__setattr__(self, "watched", MappingProxyType(dict(self.watched)))
        for name in ("k", "h_warning", "h_alarm", "clear_level", "z_cap", "statistic_cap",
                     "sd_floor_rel", "screen_sigmas", "screen_min_rel"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError(f"alarm setting {name} must be a finite number >= 0, got {value!r}")
        for name, least in (("baseline_n", 3), ("clear_count", 1), ("max_evidence_ops", 1)):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < least:
                raise ValueError(f"alarm setting {name} must be an integer >= {least}, got {value!r}")
        if not self.clear_level < self.h_warning <= self.h_alarm <= self.statistic_cap:
            raise ValueError(
                "alarm thresholds must satisfy clear_level < h_warning <= h_alarm <= statistic_cap, "
                f"got {self.clear_level} < {self.h_warning} <= {self.h_alarm} <= {self.statistic_cap}")
        if self.z_cap <= self.k:
            raise ValueError(f"alarm setting z_cap ({self.z_cap}) must exceed k ({self.k})")
        if self.sd_floor_rel <= 0:
            raise ValueError("alarm setting sd_floor_rel must be > 0")
        if not self.watched:
            raise ValueError("alarm setting watched must name at least one parameter")
        for name, direction in self.watched.items():
            if direction not in DIRECTIONS:
                raise ValueError(f"alarm direction for {name} must be one of {DIRECTIONS}, "
                                 f"got {direction!r}")

    def direction(self, parameter: str) -> str:
        """The watched direction of ``parameter``; ValueError if it is not watched."""
        try:
            return self.watched[parameter]
        except KeyError:
            raise ValueError(f"parameter {parameter!r} is not watched for drift "
                             f"(watched: {', '.join(sorted(self.watched))})") from None

    @classmethod
    def from_mapping(cls, section: Mapping[str, Any]) -> "DriftSettings":
        """Build from a config section such as ``[alarms]`` in config/default.toml.

        Unknown keys are refused, so a typo in the config cannot silently leave a default.
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(section) - known)
        if unknown:
            raise ValueError(f"unknown alarm settings: {', '.join(unknown)} "
                             f"(known: {', '.join(sorted(known))})")
        return cls(**dict(section))

    def to_dict(self) -> dict[str, Any]:
        """JSON-able copy, the inverse of ``from_mapping``."""
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["watched"] = dict(self.watched)
        return out
