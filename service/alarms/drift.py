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
from dataclasses import replace
from typing import Any

from scipy import special

from service.alarms.baseline import Model, fit_model, screen
from service.alarms.observation import (TEMPERATURE_RANGE_C, Z95, AlarmEvent, FitObservation,  # noqa: F401
                                        check_temperature, utc_text)
from service.alarms.settings import DriftSettings
from service.alarms.state import LEVELS, STATE_VERSION, Baseline, DriftState  # noqa: F401

# A temperature this far outside a frozen window's range is new to it [K]: the daily swing.
NEW_TEMPERATURE_K = 6.0


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
        raise ValueError(f"fit of operation {obs.operation_id} ({utc_text(obs.time)}) is older "
                         f"than the last one ({utc_text(state.last_time)}); replay the history")
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
    # The learnt temperature slope's error b_err is the same for every fit: its part of the
    # prediction error, b_err (T - T_mean), is a common-mode bias, not independent noise. Scored
    # as noise it would lift the CUSUM through a whole cold or hot season. So the score uses the
    # independent part of the variance only, and the reference k grows by the bias's bound,
    # common_mode_z sds of b_err times |T - T_mean|, in units of that score.
    allowance, score_band = 0.0, band
    if model.compensated and obs.temperature is not None and model.slope_var > 0:
        common = model.slope_var * (obs.temperature - model.t_mean) ** 2
        score_band = math.sqrt(max(var - common, 1e-300))
        allowance = settings.common_mode_z * math.sqrt(common) / score_band
    u = normal_score((obs.value - expected) / score_band, model.dof)
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
        # (a held fit is applied with this fit's allowance: consecutive fits, alike temperatures)
        if direction in ("rising", "both"):
            s_r, run_r, len_r = _cusum_side(s_r, zc - settings.k - allowance, run_r, len_r,
                                            operation_id, settings)
        if direction in ("falling", "both"):
            s_f, run_f, len_f = _cusum_side(s_f, -zc - settings.k - allowance, run_f, len_f,
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
