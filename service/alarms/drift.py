"""CUSUM drift detection on fitted mechanism parameters, and the alarm lifecycle.

Pure: no I/O, no wall clock. The caller owns the loop — it persists one ``DriftState`` per
(breaker, watched parameter), feeds good fits in operation order through ``update`` and stores
the ``AlarmEvent``s it returns. The method and its tuning are in docs/alarms.md.

    z_i  = (x_i - m) / sqrt(s^2 (1 + 1/n) + se_i^2)           standardised deviation [-]
    u_i  = Phi^-1(T_{n-1}(z_i))                                normal score of the predictive t
    zc_i = clip(u_i, -z_cap, z_cap)                            one fit adds at most z_cap - k
    (a fit with |u_i| > z_cap and no neighbour leaning the same way is an outlier: ignored)
    S+_i = min(S_cap, max(0, S+_{i-1} + zc_i - k))             rising drift
    S-_i = min(S_cap, max(0, S-_{i-1} - zc_i - k))             falling drift

m, s, n: the breaker's baseline mean, sd and size; se_i: the fit's standard error.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from datetime import datetime, timezone
from typing import Any, Iterable, Mapping

import numpy as np
from scipy import special
from scipy.stats import median_abs_deviation  # scale="normal": MAD of a normal sample -> its sd

from service.alarms.settings import DriftSettings

Z95 = 1.959963984540054  # two-sided 95 % normal quantile: CI half-width = Z95 * stderr
LEVELS = ("none", "warning", "alarm")
STATE_VERSION = 1


def _utc_text(t: datetime) -> str:
    return t.astimezone(timezone.utc).isoformat().replace("+00:00", "Z")


def _finite(name: str, value: Any) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(out):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return out


@dataclass(frozen=True)
class FitObservation:
    """One good fit of one watched parameter.

    operation_id : int | str — the operation the fit belongs to
    time : datetime — time of the operation, timezone-aware
    value : float — fitted value [unit of the parameter, e.g. DO s^-1, BO s^-2]
    ci95 : (lo, hi) | None — 95 % confidence interval of the fit [same unit]
    stderr : float | None — standard error of the fit [same unit]; used when ci95 is None.
        With neither, the fit's own uncertainty counts as zero.
    """

    operation_id: int | str
    time: datetime
    value: float
    ci95: tuple[float, float] | None = None
    stderr: float | None = None

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

    @property
    def se(self) -> float:
        """Standard error of the fitted value [unit of the parameter]."""
        if self.ci95 is not None:
            return (self.ci95[1] - self.ci95[0]) / (2.0 * Z95)
        return self.stderr or 0.0

    def to_dict(self) -> dict[str, Any]:
        return {"operation_id": self.operation_id, "time": _utc_text(self.time),
                "value": self.value, "ci95": list(self.ci95) if self.ci95 else None,
                "stderr": self.se}


@dataclass(frozen=True)
class Baseline:
    """A breaker's healthy reference for one parameter.

    mean, sd : screened mean and sd of the baseline fits [unit of the parameter]
    n : fits kept after screening; operation_ids: all baseline fits; excluded_ids: screened out.
    """

    mean: float
    sd: float
    n: int
    operation_ids: tuple
    excluded_ids: tuple = ()

    def to_dict(self) -> dict[str, Any]:
        return {"mean": self.mean, "sd": self.sd, "n": self.n,
                "operation_ids": list(self.operation_ids),
                "excluded_operation_ids": list(self.excluded_ids)}


def fit_baseline(operation_ids: Iterable, values: Iterable[float],
                 settings: DriftSettings) -> Baseline:
    """Baseline from the first good fits: screen gross outliers, then mean and sd of the rest.

    The MAD only screens out outliers; the mean and sd of the kept fits are far more efficient
    at n = 20 (MAD-sd has ~2.7x the variance), and an underestimated sd is what breeds false
    alarms. The sd never falls below ``sd_floor_rel * |mean|``.
    """
    ids = tuple(operation_ids)
    x = np.asarray(list(values), dtype=float)
    median = float(np.median(x))
    floor = settings.sd_floor_rel * max(abs(median), 1e-12)
    mad_sd = max(float(median_abs_deviation(x, scale="normal")), floor)
    # A fit is screened out only if it is far off in both senses: > screen_sigmas MAD-sigmas
    # and > screen_min_rel. The MAD of 20 fits is itself noisy; when it comes out small, a pure
    # MAD screen drops healthy fits and the sd collapses (false alarms). Keeping a doubtful fit
    # errs the safe way: a wider baseline, slightly slower detection.
    limit = max(settings.screen_sigmas * mad_sd, settings.screen_min_rel * abs(median))
    keep = np.abs(x - median) <= limit
    kept = x[keep]
    sd = float(np.std(kept, ddof=1)) if kept.size > 1 else mad_sd
    mean = float(np.mean(kept))
    return Baseline(mean=mean, sd=max(sd, settings.sd_floor_rel * max(abs(mean), 1e-12)),
                    n=int(kept.size), operation_ids=ids,
                    excluded_ids=tuple(i for i, k in zip(ids, keep) if not k))


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
        out["time"] = _utc_text(self.time)
        return out


@dataclass(frozen=True)
class DriftState:
    """Detector state of one watched parameter of one breaker; persist it with ``to_dict``.

    phase : "baseline" while the first ``baseline_n`` good fits are collected, then "monitoring"
    s_rising, s_falling : the two one-sided CUSUMs [z]
    run_rising, run_falling : operation ids since each CUSUM last left zero (newest last)
    level : "none" | "warning" | "alarm"; episode: number of the current or last alarm
    """

    parameter: str
    phase: str = "baseline"
    collected: tuple = ()  # ((operation_id, value), ...) while in the baseline phase
    baseline: Baseline | None = None
    s_rising: float = 0.0
    s_falling: float = 0.0
    run_rising: tuple = ()
    run_falling: tuple = ()
    run_length_rising: int = 0
    run_length_falling: int = 0
    level: str = "none"
    acknowledged: bool = False
    acknowledged_by: str | None = None
    acknowledged_at: datetime | None = None
    below_count: int = 0
    episode: int = 0
    last_operation_id: int | str | None = None
    last_time: datetime | None = None
    last_z: float | None = None
    last_score: float | None = None
    held: tuple | None = None  # (operation_id, score): an unsupported extreme fit, on hold
    outliers_ignored: int = 0
    fits_monitored: int = 0

    @classmethod
    def new(cls, parameter: str, settings: DriftSettings) -> "DriftState":
        """Fresh state: the next ``settings.baseline_n`` good fits form the baseline."""
        settings.direction(parameter)  # refuse unwatched parameters early
        return cls(parameter=parameter)

    @property
    def statistic(self) -> float:
        """The larger of the two CUSUMs [z] (only the watched sides ever leave zero)."""
        return max(self.s_rising, self.s_falling)

    @property
    def active(self) -> bool:
        return self.level != "none"

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict (no NaN); ``DriftState.from_dict`` is its inverse."""
        out = {f: getattr(self, f) for f in self.__dataclass_fields__}
        out["version"] = STATE_VERSION
        out["collected"] = [list(c) for c in self.collected]
        out["baseline"] = self.baseline.to_dict() if self.baseline else None
        out["run_rising"] = list(self.run_rising)
        out["run_falling"] = list(self.run_falling)
        out["held"] = list(self.held) if self.held is not None else None
        for key in ("acknowledged_at", "last_time"):
            out[key] = _utc_text(out[key]) if out[key] else None
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "DriftState":
        if data.get("version") != STATE_VERSION:
            raise ValueError(f"drift state version {data.get('version')!r} is not supported "
                             f"(expected {STATE_VERSION}); reset the baseline or replay the history")
        d = {k: v for k, v in data.items() if k != "version"}
        d["collected"] = tuple(tuple(c) for c in d.get("collected", ()))
        b = d.get("baseline")
        d["baseline"] = None if b is None else Baseline(
            mean=b["mean"], sd=b["sd"], n=b["n"], operation_ids=tuple(b["operation_ids"]),
            excluded_ids=tuple(b.get("excluded_operation_ids", ())))
        d["run_rising"] = tuple(d.get("run_rising", ()))
        d["run_falling"] = tuple(d.get("run_falling", ()))
        d["held"] = tuple(d["held"]) if d.get("held") is not None else None
        for key in ("acknowledged_at", "last_time"):
            if d.get(key):
                d[key] = datetime.fromisoformat(d[key])
        unknown = set(d) - set(cls.__dataclass_fields__)
        if unknown:
            raise ValueError(f"unknown drift state fields: {', '.join(sorted(unknown))}")
        return cls(**d)


def standardised_deviation(obs: FitObservation, baseline: Baseline) -> float:
    """z of one fit against the baseline [-]: baseline spread, baseline-mean error and fit CI."""
    var = baseline.sd ** 2 * (1.0 + 1.0 / baseline.n) + obs.se ** 2
    return (obs.value - baseline.mean) / math.sqrt(var)


def normal_score(z: float, n: int) -> float:
    """Map z, Student-t with n - 1 degrees of freedom, to the standard normal score [-].

    With a baseline of only n ~ 20 fits, a new fit's z follows the predictive t, not a normal:
    its tails are heavier, and treating it as normal roughly doubles the false alarms.
    """
    if n < 2:
        return z
    # isf of the upper tail keeps precision far out where cdf rounds to 1.
    return math.copysign(-float(special.ndtri(special.stdtr(n - 1, -abs(z)))), z)


def _evidence(state: DriftState, obs: FitObservation, z: float,
              settings: DriftSettings) -> dict[str, Any]:
    falling = state.s_falling >= state.s_rising
    b = state.baseline
    return {
        "parameter": state.parameter,
        "watched_direction": settings.direction(state.parameter),
        "drift_direction": "falling" if falling else "rising",
        "baseline": b.to_dict(),
        "current": {**obs.to_dict(), "z": z,
                    "change_rel": (obs.value - b.mean) / b.mean if b.mean else None},
        "statistic": state.statistic,
        "thresholds": {"k": settings.k, "warning": settings.h_warning,
                       "alarm": settings.h_alarm, "clear": settings.clear_level},
        "operation_ids": list(state.run_falling if falling else state.run_rising),
        "run_length": state.run_length_falling if falling else state.run_length_rising,
    }


def _cusum_side(s: float, increment: float, run: tuple, run_length: int, operation_id,
                settings: DriftSettings) -> tuple[float, tuple, int]:
    s = min(settings.statistic_cap, max(0.0, s + increment))
    if s == 0.0:
        return 0.0, (), 0
    run = (run + (operation_id,))[-settings.max_evidence_ops:]
    return s, run, run_length + 1


def update(state: DriftState, obs: FitObservation,
           settings: DriftSettings) -> tuple[DriftState, list[AlarmEvent]]:
    """Feed one good fit; returns the new state and the alarm events it caused.

    Fits must come in operation order. The same operation twice in a row is a no-op (so a
    retried job cannot count twice); an older fit raises ValueError — replay the history.
    """
    direction = settings.direction(state.parameter)
    if state.last_operation_id is not None and obs.operation_id == state.last_operation_id:
        return state, []
    if state.last_time is not None and obs.time < state.last_time:
        raise ValueError(f"fit of operation {obs.operation_id} ({_utc_text(obs.time)}) is older "
                         f"than the last one ({_utc_text(state.last_time)}); replay the history")
    state = replace(state, last_operation_id=obs.operation_id, last_time=obs.time)

    if state.phase == "baseline":
        collected = state.collected + ((obs.operation_id, obs.value),)
        if len(collected) < settings.baseline_n:
            return replace(state, collected=collected), []
        ids, values = zip(*collected)
        return replace(state, phase="monitoring", collected=(),
                       baseline=fit_baseline(ids, values, settings)), []

    z = standardised_deviation(obs, state.baseline)
    u = normal_score(z, state.baseline.n)
    # Persistence for extreme fits: a score beyond z_cap counts only when a neighbouring fit
    # leans the same way (|score| >= k) or that side is already at warning level. An isolated one is held for one fit, then dropped, so a
    # single bad fit adds nothing; a real step is late by one fit; a ramp is not delayed.
    to_apply, held, ignored = [], None, state.outliers_ignored
    if state.held is not None:
        held_id, held_u = state.held
        if math.copysign(1.0, held_u) == math.copysign(1.0, u) and abs(u) >= settings.k:
            to_apply.append((held_id, held_u))
        else:
            ignored += 1
    prev = state.last_score
    side = state.s_rising if u > 0 else state.s_falling
    supported = (prev is not None and prev * u > 0 and abs(prev) >= settings.k) \
        or side >= settings.h_warning  # already a warning-level excursion that way
    if abs(u) > settings.z_cap and not supported:
        held = (obs.operation_id, u)
    else:
        to_apply.append((obs.operation_id, u))

    s_r, run_r, len_r = state.s_rising, state.run_rising, state.run_length_rising
    s_f, run_f, len_f = state.s_falling, state.run_falling, state.run_length_falling
    for operation_id, score in to_apply:
        zc = min(settings.z_cap, max(-settings.z_cap, score))
        if direction in ("rising", "both"):
            s_r, run_r, len_r = _cusum_side(s_r, zc - settings.k, run_r, len_r,
                                            operation_id, settings)
        if direction in ("falling", "both"):
            s_f, run_f, len_f = _cusum_side(s_f, -zc - settings.k, run_f, len_f,
                                            operation_id, settings)
    state = replace(state, s_rising=s_r, run_rising=run_r, run_length_rising=len_r,
                    s_falling=s_f, run_falling=run_f, run_length_falling=len_f,
                    last_z=z, last_score=u, held=held, outliers_ignored=ignored,
                    fits_monitored=state.fits_monitored + 1)
    return _step_level(state, obs, z, settings)


def _step_level(state: DriftState, obs: FitObservation, z: float,
                settings: DriftSettings) -> tuple[DriftState, list[AlarmEvent]]:
    """Raise, escalate or clear (with hysteresis) from the new statistic."""
    s = state.statistic
    target = "alarm" if s >= settings.h_alarm else "warning" if s >= settings.h_warning else "none"

    def event(kind: str, st: DriftState, level: str, reason: str) -> AlarmEvent:
        return AlarmEvent(kind=kind, parameter=st.parameter, level=level, episode=st.episode,
                          operation_id=obs.operation_id, time=obs.time,
                          evidence=_evidence(st, obs, z, settings), reason=reason)

    if LEVELS.index(target) > LEVELS.index(state.level):
        if state.level == "none":
            state = replace(state, level=target, episode=state.episode + 1, below_count=0,
                            acknowledged=False, acknowledged_by=None, acknowledged_at=None)
            return state, [event("raised", state, target,
                                 f"CUSUM {s:.2f} >= {settings.h_alarm if target == 'alarm' else settings.h_warning}")]
        # Escalation is news: it needs a fresh acknowledgement.
        state = replace(state, level=target, below_count=0, acknowledged=False,
                        acknowledged_by=None, acknowledged_at=None)
        return state, [event("escalated", state, target, f"CUSUM {s:.2f} >= {settings.h_alarm}")]

    if state.level == "none":
        return state, []
    # Hysteresis: clear only after clear_count consecutive fits below clear_level.
    below = state.below_count + 1 if s < settings.clear_level else 0
    if below < settings.clear_count:
        return replace(state, below_count=below), []
    level = state.level
    state = replace(state, level="none", below_count=0)
    return state, [event("cleared", state, level,
                         f"CUSUM below {settings.clear_level} for {below} consecutive fits")]


def replay(history: Iterable[FitObservation], settings: DriftSettings, *, parameter: str,
           state: DriftState | None = None) -> tuple[DriftState, list[AlarmEvent]]:
    """Run a whole history (in operation order) from a fresh state, or from ``state``."""
    state = state if state is not None else DriftState.new(parameter, settings)
    if state.parameter != parameter:
        raise ValueError(f"state is for {state.parameter!r}, not {parameter!r}")
    events: list[AlarmEvent] = []
    for obs in history:
        state, new = update(state, obs, settings)
        events.extend(new)
    return state, events


def acknowledge(state: DriftState, *, by: str, time: datetime) -> tuple[DriftState, list[AlarmEvent]]:
    """An operator acknowledges the active alarm. Acknowledging twice is a no-op.

    The alarm stays active until the statistic clears it; an escalation needs a new ack.
    """
    if not state.active:
        raise ValueError(f"no active {state.parameter} alarm to acknowledge")
    if not isinstance(time, datetime) or time.tzinfo is None:
        raise ValueError("acknowledgement time must be a timezone-aware datetime")
    if state.acknowledged:
        return state, []
    state = replace(state, acknowledged=True, acknowledged_by=str(by), acknowledged_at=time)
    return state, [AlarmEvent(kind="acknowledged", parameter=state.parameter, level=state.level,
                              episode=state.episode, operation_id=None, time=time,
                              evidence={"acknowledged_by": str(by)}, reason=f"acknowledged by {by}")]


def reset_baseline(state: DriftState, *, by: str, time: datetime,
                   reason: str = "maintenance") -> tuple[DriftState, list[AlarmEvent]]:
    """Admin action after maintenance: the next good fits form a new baseline.

    An active alarm is cleared (the fault it reported was the reason for the maintenance).
    """
    if not isinstance(time, datetime) or time.tzinfo is None:
        raise ValueError("baseline reset time must be a timezone-aware datetime")
    events = []
    if state.active:
        events.append(AlarmEvent(
            kind="cleared", parameter=state.parameter, level=state.level, episode=state.episode,
            operation_id=None, time=time,
            evidence={"baseline": state.baseline.to_dict() if state.baseline else None,
                      "statistic": state.statistic, "reset_by": str(by)},
            reason=f"baseline reset by {by}: {reason}"))
    fresh = DriftState(parameter=state.parameter, episode=state.episode,
                       last_operation_id=state.last_operation_id, last_time=state.last_time)
    return fresh, events


def observations_from_fit(fit: Any, *, operation_id: int | str, time: datetime,
                          settings: DriftSettings) -> dict[str, FitObservation]:
    """The watched parameters of one fit (a ``FitResult`` or its ``to_dict()``) as observations.

    Only feed good fits (status ok) — a failed fit has no value to watch.
    """
    get = (lambda key: fit.get(key)) if isinstance(fit, Mapping) else (lambda key: getattr(fit, key, None))
    params, ci95, stderr = get("parameters") or {}, get("ci95") or {}, get("stderr")
    stderr = stderr if isinstance(stderr, Mapping) else {}
    out = {}
    for name in settings.watched:
        if name in params:
            ci = ci95.get(name)
            out[name] = FitObservation(operation_id=operation_id, time=time, value=params[name],
                                       ci95=tuple(ci) if ci is not None else None,
                                       stderr=stderr.get(name))
    return out


def health_status(states: Iterable[DriftState]) -> str:
    """Overall drift status of a breaker: "alarm" | "warning" | "ok" | "unknown" (no baseline yet)."""
    states = list(states)
    levels = {s.level for s in states}
    if "alarm" in levels:
        return "alarm"
    if "warning" in levels:
        return "warning"
    if not states or any(s.phase == "baseline" for s in states):
        return "unknown"
    return "ok"
