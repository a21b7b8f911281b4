"""False-alarm rates and detection delays of the drift detector, by simulation with the real code.

    nice .venv/bin/python bench/alarm_rates.py [--breakers 1000] [--ops 1020] [--workers 2]

Every simulated fit goes through ``service.alarms.update``, the function the fit job calls.
Noise model (docs/alarms.md): per breaker a run-to-run sd drawn in 1-2 %; per fit a 95 % CI
half-width drawn in 0.8-1.2 % (the measured fit CIs) and a fit error consistent with it; 1 % of
fits are gross outliers, off by 5-30 % either way. One operation a day at a random hour.

The trip latch's time (``latch_time_s``, read from the vibration, watched rising by default) is
the third watched parameter of every breaker: no interval (the read gives none), a read error of
0.049 ms sd (the withheld latch series' worst median error, 0.033 ms, over 0.6745), the same
run-to-run spread and outliers, and no temperature dependence (none is modelled for it yet).

Cases: in control (no temperature effect, none given); drifts (ramps of 1 %/op, a slow leak of
-0.1 %/op, 5 % steps) starting at operation 30 (young baseline) and 300 (frozen baseline);
seasonal temperature (-25..+40 C over a year, daily swings, DO -0.4 %/K, BO -0.03 %/K) with and
without the temperature given to the detector. Writes bench/results/alarm_rates.json.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from service.alarms import DriftSettings, DriftState, FitObservation, update  # noqa: E402

NOMINAL = {"DO": 39.5, "BO": 4806.0, "latch_time_s": 1.2e-3}  # reference breaker [s^-1], [s^-2], [s]
TEMP_SLOPE = {"DO": -0.004, "BO": -0.0003, "latch_time_s": 0.0}  # simulated temperature dependence [1/K]
PARAMETERS = tuple(NOMINAL)
LATCH_READ_SD_S = 0.033e-3 / 0.6745  # bench/vibration_series.py: median |error| <= 0.033 ms [s]
STICK_PER_OP = 0.02e-3 / 1.2e-3  # the sticking latch of bench/vibration_series.py: 0.02 ms per opening [-]
T_REF = 20.0  # [C]
Z95 = 1.959963984540054
T0 = datetime(2024, 1, 1, tzinfo=timezone.utc)
OUTLIER_P = 0.01
RESULTS = Path(__file__).resolve().parent / "results" / "alarm_rates.json"


def temperature(day: np.ndarray, hour: np.ndarray, rng) -> np.ndarray:
    """Ambient temperature [C]: -25..+40 C over a year (coldest about 20 January), a daily swing
    of +-6 K (warmest mid-afternoon) and 2 K of day-to-day weather."""
    season = 7.5 - 32.5 * np.cos(2 * np.pi * (day - 20) / 365.25)
    daily = 6.0 * np.sin(2 * np.pi * (hour - 9) / 24)
    return np.clip(season + daily + rng.normal(0, 2.0, day.size), -25.0, 40.0)


def history(rng, parameter: str, n_ops: int, *, drift: str = "none", rate: float = 0.0,
            start: int = 30, seasonal: bool = False, give_temperature: bool = False):
    """Observations of operations 1..n_ops of one breaker and one parameter.

    drift "ramp": relative change rate*(i - start) for i > start; "step": rate for i > start.
    """
    p = NOMINAL[parameter]
    sd_run = rng.uniform(0.01, 0.02)
    i = np.arange(1, n_ops + 1)
    if drift == "ramp":
        factor = 1.0 + rate * np.maximum(0, i - start)
    elif drift == "step":
        factor = np.where(i > start, 1.0 + rate, 1.0)
    else:
        factor = np.ones(n_ops)
    day0 = rng.uniform(0, 365)
    day = day0 + i
    hour = rng.uniform(0, 24, n_ops)
    temp = temperature(day, hour, rng)
    if seasonal:
        factor = factor * (1.0 + TEMP_SLOPE[parameter] * (temp - T_REF))
    latch = parameter == "latch_time_s"
    half = rng.uniform(0.008, 0.012, n_ops) * p
    read_sd = np.full(n_ops, LATCH_READ_SD_S) if latch else half / Z95
    x = p * factor * (1.0 + sd_run * rng.standard_normal(n_ops)) + read_sd * rng.standard_normal(n_ops)
    out = rng.random(n_ops) < OUTLIER_P
    x[out] *= 1.0 + rng.choice([-1.0, 1.0], out.sum()) * rng.uniform(0.05, 0.30, out.sum())
    return [FitObservation(operation_id=int(op), time=T0 + timedelta(days=float(d), hours=float(h)),
                           value=float(v), ci95=None if latch else (float(v - hw), float(v + hw)),
                           temperature=float(t) if give_temperature else None)
            for op, d, h, v, hw, t in zip(i, i, hour, x, half, temp)]


def run(history_obs, parameter: str, settings: DriftSettings):
    """Feed the history; return (monitored fits, warnings raised, alarms reached,
    first warning op, first alarm op)."""
    state = DriftState.new(parameter, settings)
    warnings = alarms = 0
    first_w = first_a = None
    for obs in history_obs:
        state, events = update(state, obs, settings)
        for e in events:
            if e.kind == "raised":
                warnings += 1
                first_w = first_w or e.operation_id
            if e.kind in ("raised", "escalated") and e.level == "alarm":
                alarms += 1
                first_a = first_a or e.operation_id
    return state.fits_monitored, warnings, alarms, first_w, first_a


def _job(args):
    kind, parameter, seeds, kw, settings_dict = args
    settings = DriftSettings.from_mapping(settings_dict)
    out = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        out.append(run(history(rng, parameter, **kw), parameter, settings))
    return kind, parameter, out


def _chunks(seq, n):
    return [seq[i:i + n] for i in range(0, len(seq), n)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--breakers", type=int, default=1000, help="in-control breakers")
    ap.add_argument("--ops", type=int, default=1020, help="operations per in-control breaker")
    ap.add_argument("--seasonal-breakers", type=int, default=1000, help="10^6 operations with 1020 each")
    ap.add_argument("--uncompensated-breakers", type=int, default=100)
    ap.add_argument("--drift-histories", type=int, default=1000, help="per drift case, onset at op 30")
    ap.add_argument("--frozen-drift-histories", type=int, default=500, help="per drift case, onset at op 300")
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--quick", action="store_true",
                    help="development size: 50 in-control, 200 seasonal, 20 uncompensated breakers, 100/50 drifts")
    ap.add_argument("--common-mode-z", type=float, default=None,
                    help="override DriftSettings.common_mode_z (0: the slope's error scored as noise)")
    ap.add_argument("--temperature-only", action="store_true",
                    help="only the cases with a temperature given (seasonal in control and the seasonal 5 %% "
                         "steps): the common-mode allowance is 0 without a temperature, so the other "
                         "figures are those of the last full run by construction")
    a = ap.parse_args(argv)
    if a.quick:
        a.breakers, a.seasonal_breakers, a.uncompensated_breakers = 50, 200, 20
        a.drift_histories, a.frozen_drift_histories = 100, 50
    settings = DriftSettings() if a.common_mode_z is None else DriftSettings(common_mode_z=a.common_mode_z)
    sd = settings.to_dict()
    uptime_before = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    t_start = time.perf_counter()

    jobs = []

    def add(kind, parameter, n, kw, case):
        if a.temperature_only and not kw.get("give_temperature"):
            return  # (the case numbers, and so every seed, stay those of the full run)
        seeds = [[a.seed, case, b] for b in range(n)]
        for ch in _chunks(seeds, 25):
            jobs.append((kind, parameter, ch, kw, sd))

    case = 0
    for p in PARAMETERS:
        case += 1
        add("control", p, a.breakers, {"n_ops": a.ops}, case)
        case += 1
        add("seasonal", p, a.seasonal_breakers,
            {"n_ops": a.ops, "seasonal": True, "give_temperature": True}, case)
        case += 1
        add("seasonal_uncompensated", p, a.uncompensated_breakers,
            {"n_ops": a.ops, "seasonal": True, "give_temperature": False}, case)
    drifts = [("ramp1", "DO", "ramp", -0.01), ("ramp1", "BO", "ramp", -0.01), ("ramp1", "BO", "ramp", +0.01),
              ("leak", "DO", "ramp", -0.001),
              ("step5", "DO", "step", -0.05), ("step5", "BO", "step", -0.05), ("step5", "BO", "step", +0.05),
              ("latch_stick", "latch_time_s", "ramp", STICK_PER_OP)]
    for start in (30, 300):
        for name, p, drift, rate in drifts:
            case += 1
            length = {"ramp1": 40, "leak": 200, "step5": 30, "latch_stick": 40}[name]
            add(f"{name}@{start}", p, a.drift_histories if start == 30 else a.frozen_drift_histories,
                {"n_ops": start + length, "drift": drift, "rate": rate, "start": start}, case)

    # The same 5 % steps on breakers with the seasonal temperature given (compensated), onset
    # at 300: the common-mode allowance must not slow their detection much.
    for p, rate in (("DO", -0.05), ("BO", -0.05), ("BO", +0.05)):
        case += 1
        add("step5_seasonal@300", p, a.frozen_drift_histories,
            {"n_ops": 330, "drift": "step", "rate": rate, "start": 300, "seasonal": True,
             "give_temperature": True}, case)
    results: dict = {}
    with ProcessPoolExecutor(max_workers=a.workers) as pool:
        for kind, parameter, out in pool.map(_job, jobs):
            results.setdefault((kind, parameter), []).extend(out)
    elapsed = time.perf_counter() - t_start

    def rates(kind):
        ops = {p: sum(r[0] for r in results[(kind, p)]) for p in PARAMETERS}
        breakers = len(results[(kind, "DO")])
        per_breaker_ops = ops["DO"] / breakers  # every parameter of a breaker sees the same operations
        w = sum(r[1] for p in PARAMETERS for r in results[(kind, p)])
        al = sum(r[2] for p in PARAMETERS for r in results[(kind, p)])
        total_ops = per_breaker_ops * breakers
        return total_ops, w / total_ops * 1e4, al / total_ops * 1e4

    def delays(kind, parameters, start, level=4):
        """Delays [ops after the onset] of the first alarm (level 4) or warning (3); a history
        that alarmed before the onset or never is counted apart."""
        d, missed = [], 0
        for p in parameters:
            for r in results[(kind, p)]:
                op = r[level]
                if op is None or op <= start:
                    missed += 1
                else:
                    d.append(op - start)
        return np.array(d), missed

    se_ops, se_w, se_a = rates("seasonal")
    out = {"temperature_only": a.temperature_only}
    if not a.temperature_only:
        ic_ops, ic_w, ic_a = rates("control")
        by = {}
        for p in PARAMETERS:
            ops_p = sum(r[0] for r in results[("control", p)])
            by[p] = {"false_warnings_per_10k_ops": round(sum(r[1] for r in results[("control", p)]) / ops_p * 1e4, 4),
                     "false_alarms_per_10k_ops": round(sum(r[2] for r in results[("control", p)]) / ops_p * 1e4, 4)}
        out["in_control_by_parameter"] = by
        out.update({"in_control_operations": int(ic_ops), "in_control_breakers": a.breakers,
               "false_warnings_per_10k_ops": round(ic_w, 4), "false_alarms_per_10k_ops": round(ic_a, 4)})
        for start in (30, 300):
            sfx = "" if start == 30 else "_frozen_baseline"
            d, missed = delays(f"ramp1@{start}", ["DO", "BO"], start)
            out[f"ramp_1pct_delay_median_ops{sfx}"] = float(np.median(d))
            out[f"ramp_1pct_delay_p95_ops{sfx}"] = float(np.percentile(d, 95))
            out[f"ramp_1pct_delay_max_ops{sfx}"] = int(d.max())
            out[f"ramp_1pct_not_after_onset{sfx}"] = int(missed)
            dl, ml = delays(f"leak@{start}", ["DO"], start)
            drop = dl * 0.1  # % fallen when the alarm came
            out[f"ramp_0p1pct_detect_median_drop_pct{sfx}"] = float(np.median(drop)) if drop.size else None
            out[f"ramp_0p1pct_detect_p95_drop_pct{sfx}"] = float(np.percentile(drop, 95)) if drop.size else None
            out[f"ramp_0p1pct_missed_or_early{sfx}"] = int(ml)
            ds, ms = delays(f"step5@{start}", ["DO", "BO"], start)
            out[f"step_5pct_delay_median_ops{sfx}"] = float(np.median(ds))
            out[f"step_5pct_delay_p95_ops{sfx}"] = float(np.percentile(ds, 95))
            out[f"step_5pct_within_3_ops_fraction{sfx}"] = round(float(np.mean(ds <= 3)), 4)
            out[f"step_5pct_not_after_onset{sfx}"] = int(ms)
            dl_, ml_ = delays(f"latch_stick@{start}", ["latch_time_s"], start)
            out[f"latch_stick_delay_median_ops{sfx}"] = float(np.median(dl_)) if dl_.size else None
            out[f"latch_stick_delay_max_ops{sfx}"] = int(dl_.max()) if dl_.size else None
            out[f"latch_stick_not_after_onset{sfx}"] = int(ml_)
            dw = delays(f"ramp1@{start}", ["DO", "BO"], start, level=3)[0]
            out[f"ramp_1pct_warning_delay_median_ops{sfx}"] = float(np.median(dw))
    ds, ms = delays("step5_seasonal@300", ["DO", "BO"], 300)
    out.update({"step_5pct_seasonal_compensated_delay_median_ops": float(np.median(ds)),
                "step_5pct_seasonal_compensated_delay_p95_ops": float(np.percentile(ds, 95)),
                "step_5pct_seasonal_compensated_within_3_ops_fraction": round(float(np.mean(ds <= 3)), 4),
                "step_5pct_seasonal_compensated_not_after_onset": int(ms)})
    if not a.temperature_only:
        su_ops, su_w, su_a = rates("seasonal_uncompensated")
        out.update({"seasonal_uncompensated_operations": int(su_ops),
                    "seasonal_false_warnings_per_10k_ops_uncompensated": round(su_w, 4),
                    "seasonal_false_alarms_per_10k_ops_uncompensated": round(su_a, 4)})
    out.update({"seasonal_operations": int(se_ops),
                "seasonal_false_warnings_per_10k_ops": round(se_w, 4),
                "seasonal_false_alarms_per_10k_ops": round(se_a, 4),
                "drift_histories_per_case": a.drift_histories,
                "frozen_drift_histories_per_case": a.frozen_drift_histories,
                "watched": dict(settings.watched), "sides": settings.sides,
                "designed_false_warnings_per_10k_ops": settings.design_false_warnings_per_10k,
                "designed_false_alarms_per_10k_ops": settings.design_false_alarms_per_10k,
                "uptime_before": uptime_before, "uptime_after": subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip(),
                "thresholds": {"k": settings.k, "h_warning": round(settings.h_warning, 4),
                               "h_alarm": round(settings.h_alarm, 4), "z_cap": settings.z_cap,
                               "baseline_n": settings.baseline_n, "baseline_max": settings.baseline_max,
                               "common_mode_z": settings.common_mode_z},
                "targets": {"false_warnings_per_10k_ops": 0.5, "false_alarms_per_10k_ops": 0.05,
                            "ramp_1pct_delay_median_ops": 6, "ramp_1pct_delay_p95_ops": 10,
                            "ramp_0p1pct_detect_median_drop_pct": 8, "step_5pct_delay_median_ops": 3},
                "seed": a.seed, "runtime_s": round(elapsed, 1), "workers": a.workers})
    print(json.dumps(out, indent=2))
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
