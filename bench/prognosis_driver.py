"""The one driver of the prognosis benches (issue 50 item 5): the own bench (bench/prognosis.py)
and the blind shapes (bench/prognosis_blind.py) feed their histories through it, so both count
the same way.

- **The code path**: every fit goes through ``service.alarms.update`` (the fit job's detector),
  and the prognosis is ``service.prognosis.prognose`` on that state and the fits since the reset
  (or since a logged maintenance entry, which restarts the detector with
  ``service.alarms.maintenance.restart`` as the service does), as the worker computes it.
- **One crossing count**: the truth is the number of further operations until the first one
  whose noise-free level is past the limit the prognosis used: with the operation's 0-based
  index c and j fits fed (the prognosis's "now" is fit j - 1), truth = c + 1 - j, and 0 when
  c < j ("crossed: service is due"). The prognosis's quantiles count the same way (whole
  operations from now; mixture.py).
- **One truth rule**: a truth that never crosses, or crosses beyond the prognosis's horizon, is
  "beyond the horizon" and is covered when the 95 % quantile is beyond it (None); any other
  truth is covered when p05 <= truth <= p95, a None p95 being beyond the horizon. A "no trend"
  answer has no median and no p95: [p05, beyond the horizon).
- **Counts with their Wilson 95 % intervals** (Wilson 1927): coverage per shape and overall.
"""

from __future__ import annotations

import json
import math
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from datetime import timedelta
from pathlib import Path

import numpy as np

from service.alarms import DriftSettings, DriftState, FitObservation, update
from service.alarms.maintenance import restart
from service.breaker_limits import ParameterLimit
from service.prognosis import calibration as cal_
from service.prognosis import compensated, prognose

Z95 = 1.959964
_EPS = timedelta(microseconds=1)  # a logged entry is done just before the fit it restarts from


@dataclass
class Case:
    """One history to ask: observations, where to ask, and the truth.

    obs : the fits, oldest first; stops : fits fed (1-based counts) at which to ask;
    fractions : a label per stop (0.5: halfway); true_level(state) : the noise-free level of every
    operation in the prognosis's frame, given the detector's state then [unit] (None: healthy,
    judged by its median only); times_s : operation times [s] (dates), or None;
    maintenance : [(fit index, kind)]: logged entries (the detector restarts at that fit's time)
    due : fits fed (1-based counts) at which the prognosis is also made, as the worker makes it
        when due, but not asked: its forecasts are what the calibration scores the later fits on
    """

    name: str
    parameter: str
    limit: ParameterLimit
    obs: list
    stops: list
    fractions: list
    true_level: object = None
    times_s: np.ndarray | None = None
    maintenance: list = field(default_factory=list)
    extra: dict = field(default_factory=dict)
    due: list = field(default_factory=list)


def first_past(level: np.ndarray, bound: float, direction: str) -> int | None:
    """0-based index of the first operation whose level is past ``bound``."""
    past = level <= bound if direction == "falling" else level >= bound
    idx = np.flatnonzero(past)
    return int(idx[0]) if idx.size else None


def truth_of(level: np.ndarray, bound: float, direction: str, j: int) -> float:
    """Further operations to the crossing after ``j`` fits fed; inf: never (within the path)."""
    c = first_past(level, bound, direction)
    return math.inf if c is None else float(max(c + 1 - j, 0))


def covered(pred, truth, horizon: float | None) -> bool:
    """The one truth rule (module docstring)."""
    lo, _, hi = pred
    lo = math.inf if lo is None else lo
    hi = math.inf if hi is None else hi
    if truth is None:
        return False
    beyond = math.isinf(truth) or (horizon is not None and truth > horizon)
    if beyond:
        return math.isinf(hi)
    return lo <= truth <= hi


def observe(cal, state: DriftState, o: FitObservation):
    """The calibration after fit ``o`` (service.prognosis.calibration.score), compensated as the
    prognosis compensates it; unchanged while the detector learns its baseline."""
    if not cal.forecasts or state.model is None:
        return cal
    y, w, _ = compensated(state, [o])
    return cal_.score(cal, float(y[0]), state.model.sd / math.sqrt(max(float(w[0]), 1e-12)), o.operation_id)


def after_prognosis(cal, prog):
    """The calibration after a prognosis: its forecast pending, and a crossing judged."""
    if prog.status == "crossed":
        cal = cal_.crossed(cal)
    if prog.forecast:
        q = prog.operations_to_limit
        crossing = None if q is None or prog.status != "ok" else (q.p05, q.p95)
        cal = cal_.issue(cal, prog.forecast["ahead"], prog.forecast["median"], prog.forecast["lo"],
                         prog.forecast["hi"], crossing)
    return cal


def run_case(case: Case, settings: DriftSettings, *, calibrate: bool = True, restart_at: int | None = None) -> list[dict]:
    """Feed the case's fits, ask at each stop, and return one row per question.

    calibrate : the breaker's own forecast scores correct the interval (calibration.py);
    restart_at : after this many fits the detector's and the calibration's states go through
        their JSON (a worker restart), as the service stores them
    """
    state, rows, k = DriftState.new(case.parameter, settings), [], 0
    cal = cal_.Calibration(key="reset")
    since = 0  # first fit the prognosis sees: the last logged maintenance's
    log = dict(case.maintenance)
    due = set(case.due) if calibrate else set()
    for j, o in enumerate(case.obs, start=1):
        i = j - 1
        if i in log:
            state, _ = restart(state, kind=log[i], done_at=o.time - _EPS, by="bench")
            since = i
            cal = cal_.Calibration(key=f"maintenance at fit {i}")
        state, _ = update(state, o, settings)
        if calibrate:
            cal = observe(cal, state, o)
        if restart_at is not None and j == restart_at:
            state = DriftState.from_dict(json.loads(json.dumps(state.to_dict())))
            cal = cal_.Calibration.from_dict(json.loads(json.dumps(cal.to_dict())), key=cal.key)
        if j in due and j != case.stops[k]:
            cal = after_prognosis(cal, prognose(state, case.obs[since:j], case.limit, calibration=cal))
            continue
        if j != case.stops[k]:
            continue
        t0 = time.perf_counter()
        prog = prognose(state, case.obs[since:j], case.limit, calibration=cal if calibrate else None)
        cost = time.perf_counter() - t0
        if calibrate:
            cal = after_prognosis(cal, prog)
        q, dq = prog.operations_to_limit, prog.date_to_limit
        row = {"case": case.name, "parameter": case.parameter, "at": j, "fraction": case.fractions[k],
               "status": prog.status, "alarm": state.level, "basis": prog.basis, "cost_ms": cost * 1e3,
               "pred": [None, None, None] if q is None else [q.p05, q.median, q.p95],
               "horizon": prog.horizon_operations, "rate_per_day": prog.rate_per_day,
               "change_before_crossing": prog.change_before_crossing, "notes": list(prog.notes),
               "paths": prog.paths, "calibration": prog.calibration, **case.extra}
        if case.times_s is not None:
            now = o.time
            row["pred_days"] = ([None, None, None] if dq is None else
                                [None if d is None else (d - now).total_seconds() / 86400.0
                                 for d in (dq.p05, dq.median, dq.p95)])
        if case.true_level is not None:
            truth = truth_days = None
            if prog.limit is not None:
                level = case.true_level(state)
                truth = truth_of(level, prog.limit, prog.direction, j)
                if case.times_s is not None:
                    c = first_past(level, prog.limit, prog.direction)
                    truth_days = (math.inf if c is None else
                                  max((case.times_s[c] - case.times_s[j - 1]) / 86400.0, 0.0))
            row.update(truth=truth, truth_days=truth_days)
        rows.append(row)
        k += 1
        if k == len(case.stops):
            break
    return rows


def wilson(k: int, n: int) -> list[float] | None:
    """Wilson's 95 % score interval of k successes in n (Wilson 1927)."""
    if n == 0:
        return None
    p = k / n
    den = 1 + Z95 ** 2 / n
    mid = (p + Z95 ** 2 / (2 * n)) / den
    half = Z95 * math.sqrt(p * (1 - p) / n + Z95 ** 2 / (4 * n * n)) / den
    return [round(mid - half, 4), round(mid + half, 4)]


def stats_of(sel: list[dict]) -> dict | None:
    """Coverage (with its Wilson interval), where the misses lie, the median's error at halfway
    (an infinite error for a "no trend" answer or a None median), the date interval's coverage."""
    if not sel:
        return None
    cov = [covered(r["pred"], r["truth"], r["horizon"]) for r in sel]
    below = [r["truth"] is not None and r["pred"][0] is not None and r["truth"] < r["pred"][0] for r in sel]
    half = [r for r in sel if r["fraction"] == 0.5]
    errs = [abs((r["pred"][1] if r["pred"][1] is not None else math.inf) - r["truth"]) / max(r["truth"], 1)
            for r in half if r["truth"] is not None and math.isfinite(r["truth"])]
    dated = [r for r in sel if r.get("rate_per_day") is not None and r.get("truth_days") is not None]
    dcov = [covered(r["pred_days"], r["truth_days"], None if r["horizon"] is None else
                    r["horizon"] / r["rate_per_day"]) for r in dated]
    k = int(np.sum(cov))
    return {"predictions": len(sel), "coverage_90": round(k / len(sel), 4), "wilson_95": wilson(k, len(sel)),
            "coverage_90_at_half": round(float(np.mean([covered(r["pred"], r["truth"], r["horizon"]) for r in half])), 4)
            if half else None,
            "truth_below_p05": round(float(np.mean(below)), 4),
            "truth_above_p95": round(1 - float(np.mean(below)) - k / len(sel), 4),
            "median_rel_error_at_half": round(float(np.median(errs)), 4) if errs else None,
            "date_coverage_90": round(float(np.mean(dcov)), 4) if dcov else None,
            "with_alarm": round(float(np.mean([r["alarm"] != "none" for r in sel])), 4)}


def healthy_stats(sel: list[dict], true_share: float | None = None) -> dict | None:
    """Healthy histories: the share whose median crossing lies within the horizon."""
    if not sel:
        return None
    k = int(sum(r["pred"][1] is not None for r in sel))
    out = {"breakers": len(sel), "predicted_crossing_within_horizon": round(k / len(sel), 4),
           "wilson_95": wilson(k, len(sel))}
    if true_share is not None:
        out.update(true_crossing_within_horizon=round(true_share, 4), target_at_most=round(2 * true_share + 0.01, 4),
                   met=k / len(sel) <= 2 * true_share + 0.01)
    return out


def costs(rows: list[dict]) -> dict:
    c = [r["cost_ms"] for r in rows]
    return {"median": round(float(np.median(c)), 3), "p99": round(float(np.percentile(c, 99)), 3)} if c else {}


def observation(i: int, when, value: float, half: float, temperature: float | None) -> FitObservation:
    return FitObservation(operation_id=i + 1, time=when, value=float(value), ci95=(float(value - half), float(value + half)),
                          temperature=None if temperature is None else float(temperature))


def run_parts(job, jobs: list, *, workers: int, part: int | None, parts: int, parts_dir: Path) -> list[dict] | None:
    """Run ``job`` over ``jobs`` (all of them, or the ``part``-th of ``parts`` interleaved slices,
    saved to ``parts_dir``/part_K.json so that a long bench runs in resumable chunks); returns
    the rows when every part is there, else None."""
    mine = jobs if part is None else jobs[part::parts]
    with ProcessPoolExecutor(workers) as ex:
        rows = [r for chunk in ex.map(job, mine) for r in chunk]
    if part is None:
        return rows
    parts_dir.mkdir(parents=True, exist_ok=True)
    (parts_dir / f"part_{part}.json").write_text(json.dumps({"rows": rows, "uptime": uptime()}, default=_json))
    return merge_parts(parts_dir, parts)


def merge_parts(parts_dir: Path, parts: int) -> list[dict] | None:
    files = [parts_dir / f"part_{k}.json" for k in range(parts)]
    if not all(f.exists() for f in files):
        return None
    return [r for f in files for r in json.loads(f.read_text())["rows"]]


def _json(x):
    if isinstance(x, float) and math.isinf(x):
        return "inf"
    raise TypeError(repr(x))


def uptime() -> str:
    import subprocess

    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
