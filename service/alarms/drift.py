"""Self-starting CUSUM drift detection on fitted mechanism parameters, and the alarm lifecycle.

Pure: no I/O, no wall clock. The caller owns the loop: it persists one ``DriftState`` per
(breaker, watched parameter), feeds good fits in operation order through ``update`` and stores
the ``AlarmEvent``s it returns. The method and its design are in docs/alarms.md.

    (mean_i, V_i) = baseline model's prediction of fit i at its temperature (baseline.py)
    z_i  = (x_i - mean_i) / sqrt(V_i)                          predictive t, dof of the window
    u_i  = Phi^-1(T_dof(z_i))                                  self-starting score (Hawkins 1987)
    zc_i = clip(u_i, -z_cap, z_cap)                            one fit adds at most z_cap - k
    (a fit with |u_i| > z_cap and no neighbour leaning the same way is an outlier: ignored)
    S+_i = min(S_cap, max(0, S+_{i-1} + zc_i - k))             rising drift
    S-_i = min(S_cap, max(0, S-_{i-1} - zc_i - k))             falling drift

The baseline window keeps learning (fit i joins it, winsorised at z_cap, when the CUSUM was at
zero before fit i and no alarm is active) until it holds ``baseline_max`` fits, then freezes.
While it learns, the scores u_i of an in-control breaker are independent N(0, 1), so the
known-parameter run length (design.py) is the run length of this breaker too.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from datetime import datetime, timezone
from typing import Any, Mapping

from scipy import special

from service.alarms.baseline import Model, fit_model, screen
from service.alarms.settings import DriftSettings

Z95 = 1.959963984540054  # two-sided 95 % normal quantile: CI half-width = Z95 * stderr
LEVELS = ("none", "warning", "alarm")
STATE_VERSION = 2
# Plausible temperature of a breaker mechanism [C]: outside this a reading is a sensor fault.
TEMPERATURE_RANGE_C = (-60.0, 100.0)
# A temperature this far outside a frozen window's range is new to it [K]: the daily swing.
NEW_TEMPERATURE_K = 6.0


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
        return {"operation_id": self.operation_id, "time": _utc_text(self.time),
                "value": self.value, "ci95": list(self.ci95) if self.ci95 else None,
                "stderr": self.se, "temperature": self.temperature}


@dataclass(frozen=True)
class Baseline:
    """Summary of a breaker's learnt baseline of one parameter (for evidence and the page).

    mean, sd : expected value (at the window's mean temperature) and run-to-run sd [unit]
    n : fits in the window; operation_ids: the window's fits; excluded_ids: screened out
    slope : temperature slope [unit/K] (0 without compensation); t_mean, t_span [C, K]
    compensated : the model uses temperature; frozen : the window has stopped learning
    """

    mean: float
    sd: float
    n: int
    operation_ids: tuple
    excluded_ids: tuple = ()
    slope: float = 0.0
    slope_sd: float = 0.0
    t_mean: float | None = None
    t_span: float = 0.0
    compensated: bool = False
    frozen: bool = False

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["operation_ids"] = list(self.operation_ids)
        out["excluded_operation_ids"] = list(out.pop("excluded_ids"))
        return out


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
    collected : ((operation_id, value, temperature, se), ...) while in the baseline phase
    window : the baseline's fits, same tuples (values winsorised); model : its predictive model
    frozen : the window has stopped learning
    s_rising, s_falling : the two one-sided CUSUMs [z]
    run_rising, run_falling : operation ids since each CUSUM last left zero (newest last)
    level : "none" | "warning" | "alarm"; episode: number of the current or last alarm
    """

    parameter: str
    phase: str = "baseline"
    collected: tuple = ()
    window: tuple = ()
    excluded_ids: tuple = ()
    model: Model | None = None
    frozen: bool = False
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
    last_expected: float | None = None
    last_band: float | None = None
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

    @property
    def compensated(self) -> bool:
        """The baseline model uses the temperature."""
        return self.model is not None and self.model.compensated

    @property
    def baseline(self) -> Baseline | None:
        m = self.model
        if m is None:
            return None
        return Baseline(mean=m.centre, sd=m.sd, n=m.n, operation_ids=tuple(w[0] for w in self.window),
                        excluded_ids=self.excluded_ids, slope=m.slope, slope_sd=math.sqrt(m.slope_var),
                        t_mean=m.t_mean, t_span=m.t_span, compensated=m.compensated, frozen=self.frozen)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict (no NaN); ``DriftState.from_dict`` is its inverse."""
        out = {f: getattr(self, f) for f in self.__dataclass_fields__}
        out["version"] = STATE_VERSION
        for key in ("collected", "window"):
            out[key] = [list(c) for c in out[key]]
        out["excluded_ids"] = list(self.excluded_ids)
        out["model"] = self.model.to_dict() if self.model else None
        # The summary, for readers of the stored state (retention keeps these operations' captures).
        out["baseline"] = self.baseline.to_dict() if self.model else None
        out["run_rising"] = list(self.run_rising)
        out["run_falling"] = list(self.run_falling)
        out["held"] = list(self.held) if self.held is not None else None
        for key in ("acknowledged_at", "last_time"):
            out[key] = _utc_text(out[key]) if out[key] else None
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "DriftState":
        if data.get("version") == 1:
            data = _from_version_1(data)
        if data.get("version") != STATE_VERSION:
            raise ValueError(f"drift state version {data.get('version')!r} is not supported "
                             f"(expected {STATE_VERSION}); reset the baseline or replay the history")
        d = {k: v for k, v in data.items() if k not in ("version", "baseline")}
        for key in ("collected", "window"):
            d[key] = tuple(tuple(c) for c in d.get(key, ()))
        d["excluded_ids"] = tuple(d.get("excluded_ids", ()))
        d["model"] = Model.from_dict(d["model"]) if d.get("model") else None
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


def _from_version_1(data: Mapping[str, Any]) -> dict[str, Any]:
    """A state of the frozen-20-fit detector (version 1) as a version-2 state: its baseline
    stays frozen (v1 kept only mean, sd and n, not the fits to learn from) and its CUSUM, level
    and episode carry on, so stored alarms stay in step. A baseline reset starts the learning
    baseline."""
    d = {k: v for k, v in data.items() if k not in ("baseline", "version")}
    b = data.get("baseline")
    d["version"] = STATE_VERSION
    d["collected"] = [[c[0], c[1], None, 0.0] for c in data.get("collected", ())]
    if b is not None:
        d["model"] = Model(n=int(b["n"]), dof=max(int(b["n"]) - 1, 1), centre=float(b["mean"]),
                           slope=0.0, slope_var=0.0, sd=float(b["sd"]), se2_mean=0.0).to_dict()
        d["window"] = [[i, float(b["mean"]), None, 0.0] for i in b.get("operation_ids", ())]
        d["excluded_ids"] = list(b.get("excluded_operation_ids", ()))
        d["frozen"] = True
    return d


def normal_score(z: float, dof: int) -> float:
    """Map z, Student-t with ``dof`` degrees of freedom, to the standard normal score [-].

    The predictive t of a new fit against a baseline of n fits (Hawkins 1987): its tails are
    heavier than a normal's, and treating it as normal multiplies the false alarms.
    """
    if dof < 1:
        return z
    # isf of the upper tail keeps precision far out where cdf rounds to 1.
    return math.copysign(-float(special.ndtri(special.stdtr(dof, -abs(z)))), z)


def t_for_score(u: float, dof: int) -> float:
    """Inverse of ``normal_score``: the predictive t whose normal score is ``u`` [-]."""
    return -float(special.stdtrit(dof, special.ndtr(-u)))


def _model(window: tuple, parameter: str, settings: DriftSettings,
           previous: Model | None = None) -> Model:
    _, values, temps, ses = zip(*window)
    return fit_model(values, temps, ses, slope_range=settings.slope_range(parameter),
                     sd_floor_rel=settings.sd_floor_rel, previous=previous)


def _start_monitoring(state: DriftState, collected: tuple, settings: DriftSettings) -> DriftState:
    """The first baseline: screen gross outliers out of the collected fits, fit the model."""
    ids, values, temps, _ = zip(*collected)
    keep = screen(values, temps, slope_range=settings.slope_range(state.parameter),
                  screen_sigmas=settings.screen_sigmas, screen_min_rel=settings.screen_min_rel,
                  sd_floor_rel=settings.sd_floor_rel)
    window = tuple(c for c, k in zip(collected, keep) if k)
    model = _model(window, state.parameter, settings)
    return replace(state, phase="monitoring", collected=(), window=window,
                   excluded_ids=tuple(i for i, k in zip(ids, keep) if not k),
                   model=model, frozen=len(collected) >= settings.baseline_max and _frozen(
                       collected, model, settings))


def _frozen(window: tuple, model: Model, settings: DriftSettings) -> bool:
    """The window stops learning once it is big enough and, when compensated, has spanned
    enough temperature; it never grows past ``baseline_hard_max``."""
    n = len(window)
    if n >= settings.baseline_hard_max:
        return True
    return n >= settings.baseline_max and (not model.compensated
                                           or model.t_span >= settings.temperature_span_k)


def _evidence(state: DriftState, obs: FitObservation, z: float,
              settings: DriftSettings) -> dict[str, Any]:
    falling = state.s_falling >= state.s_rising
    b = state.baseline
    expected = state.last_expected
    return {
        "parameter": state.parameter,
        "watched_direction": settings.direction(state.parameter),
        "drift_direction": "falling" if falling else "rising",
        "baseline": b.to_dict(),
        "temperature_compensated": b.compensated,
        "current": {**obs.to_dict(), "z": z, "expected": expected, "band_sd": state.last_band,
                    "change_rel": (obs.value - expected) / expected if expected else None},
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
    entry = (obs.operation_id, obs.value, obs.temperature, obs.se)

    if state.phase == "baseline":
        collected = state.collected + (entry,)
        if len(collected) < settings.baseline_n:
            return replace(state, collected=collected), []
        return _start_monitoring(state, collected, settings), []

    model = state.model
    expected, var = model.predict(obs.temperature, obs.se)
    band = math.sqrt(var)
    z = (obs.value - expected) / band
    u = normal_score(z, model.dof)
    # Persistence for extreme fits: a score beyond z_cap counts only when a neighbouring fit
    # backs it: it leans the same way (|score| >= k) and lies within z_cap of it (a ramp or a
    # step moves the scores together; a gross fit error jumps away from its neighbours), or
    # that side is already at warning level. An isolated one is held for one fit, then dropped,
    # so a single bad fit adds nothing; a real step is late by one fit; a ramp is not delayed.
    def backs(a: float | None, b: float) -> bool:
        return a is not None and a * b > 0 and abs(a) >= settings.k and abs(a - b) <= settings.z_cap

    to_apply, held, ignored = [], None, state.outliers_ignored
    if state.held is not None:
        held_id, held_u = state.held
        if backs(u, held_u):
            to_apply.append((held_id, held_u))
        else:
            ignored += 1
    side = state.s_rising if u > 0 else state.s_falling
    supported = backs(state.last_score, u) or side >= settings.h_warning
    if abs(u) > settings.z_cap and not supported:
        held = (obs.operation_id, u)
    else:
        to_apply.append((obs.operation_id, u))

    # Learning while quiet: the decision uses only the state before this fit, never this fit's
    # value, so the window stays unbiased in control; once a drift lifts the CUSUM, its fits stop
    # entering the baseline. A temperature-compensated window also learns the slope, whose error
    # is shared by consecutive fits: starving it whenever the CUSUM leaves zero would turn a slope
    # error into an alarm, so it learns while the CUSUM is below the warning level.
    calm = state.statistic < settings.h_warning if model.compensated else state.statistic == 0.0
    quiet = calm and state.level == "none" and state.held is None
    window, new_model, frozen = state.window, model, state.frozen
    # A frozen compensated window still learns a temperature it has not seen (beyond its range by
    # more than the daily swing), up to baseline_hard_max: it widens until it spans the seasons.
    unseen = (model.compensated and obs.temperature is not None
              and (obs.temperature < model.t_min - NEW_TEMPERATURE_K
                   or obs.temperature > model.t_max + NEW_TEMPERATURE_K)
              and len(window) < settings.baseline_hard_max)
    if quiet and (not frozen or unseen):
        lim = t_for_score(settings.z_cap, model.dof) * band  # Huber-type winsorised update
        value = min(expected + lim, max(expected - lim, obs.value))
        window = window + ((obs.operation_id, value, obs.temperature, obs.se),)
        new_model = _model(window, state.parameter, settings, previous=model)
        frozen = _frozen(window, new_model, settings)
        if frozen and new_model.ts_n != len(window):  # the model it freezes with: slope refit
            new_model = _model(window, state.parameter, settings)

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
                    last_z=z, last_score=u, last_expected=expected, last_band=band, held=held,
                    outliers_ignored=ignored, fits_monitored=state.fits_monitored + 1,
                    window=window, model=new_model, frozen=frozen)
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


_MOVED = ("acknowledge", "reset_baseline", "health_status", "replay", "observations_from_fit")


def __getattr__(name: str):
    """The lifecycle helpers live in actions.py; ``drift.replay`` etc. keep working."""
    if name in _MOVED:
        from service.alarms import actions

        return getattr(actions, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
