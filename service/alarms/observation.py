"""What the detector is fed and what it answers: one good fit of one watched parameter
(``FitObservation``) and a change of an alarm (``AlarmEvent``). Pure records with their checks."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from typing import Any

Z95 = 1.959963984540054  # two-sided 95 % normal quantile: CI half-width = Z95 * stderr
# Plausible temperature of a breaker mechanism [C]: outside this a reading is a sensor fault.
TEMPERATURE_RANGE_C = (-60.0, 100.0)


def utc_text(t: datetime) -> str:
    return t.astimezone(timezone.utc).isoformat().replace("+00:00", "Z")


def _finite(name: str, value: Any) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(out):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return out


def check_temperature(value: Any, where: str = "temperature_c") -> float | None:
    """A temperature [C] checked for sense, or None; ValueError in words otherwise."""
    if value is None:
        return None
    t = _finite(where, value)
    lo, hi = TEMPERATURE_RANGE_C
    if not lo <= t <= hi:
        raise ValueError(f"{where} {t:g} C is outside {lo:g}..{hi:g} C (a sensor fault, or not Celsius)")
    return t


@dataclass(frozen=True)
class FitObservation:
    """One good fit of one watched parameter.

    operation_id : int | str — the operation the fit belongs to
    time : datetime — time of the operation, timezone-aware
    value : float — fitted value [unit of the parameter, e.g. DO s^-1, BO s^-2]
    ci95 : (lo, hi) | None — 95 % confidence interval of the fit [same unit]
    stderr : float | None — standard error of the fit [same unit]; used when ci95 is None.
        With neither, the fit's own uncertainty counts as zero.
    temperature : float | None — ambient or mechanism temperature of the operation [C]
    """

    operation_id: int | str
    time: datetime
    value: float
    ci95: tuple[float, float] | None = None
    stderr: float | None = None
    temperature: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.time, datetime) or self.time.tzinfo is None:
            raise ValueError(f"fit time must be a timezone-aware datetime, got {self.time!r}")
        object.__setattr__(self, "value", _finite("fitted value", self.value))
        if self.ci95 is not None:
            lo, hi = (_finite("ci95 bound", b) for b in self.ci95)
            if hi < lo:
                raise ValueError(f"ci95 has negative width: ({lo}, {hi})")
            object.__setattr__(self, "ci95", (lo, hi))
        if self.stderr is not None:
            se = _finite("stderr", self.stderr)
            if se < 0:
                raise ValueError(f"stderr must be >= 0, got {se}")
            object.__setattr__(self, "stderr", se)
        object.__setattr__(self, "temperature", check_temperature(self.temperature, "temperature"))

    @property
    def se(self) -> float:
        """Standard error of the fitted value [unit of the parameter]."""
        if self.ci95 is not None:
            return (self.ci95[1] - self.ci95[0]) / (2.0 * Z95)
        return self.stderr or 0.0

    def to_dict(self) -> dict[str, Any]:
        return {"operation_id": self.operation_id, "time": utc_text(self.time),
                "value": self.value, "ci95": list(self.ci95) if self.ci95 else None,
                "stderr": self.se, "temperature": self.temperature}



@dataclass(frozen=True)
class AlarmEvent:
    """A change of an alarm, for the service to store.

    kind : "raised" | "escalated" | "acknowledged" | "cleared"
    level : "warning" | "alarm" — the level after the event (for "cleared", the level it had)
    episode : int — numbers the alarms of one DriftState; events of one alarm share it
    evidence : JSON-able dict (baseline, current estimate and CI, statistic, operation ids)
    """

    kind: str
    parameter: str
    level: str
    episode: int
    operation_id: int | str | None
    time: datetime
    evidence: dict[str, Any]
    reason: str = ""

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["time"] = utc_text(self.time)
        return out
