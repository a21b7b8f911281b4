"""The prognosis on the blind degradation shapes (bench/prognosis_shapes_blind.py), through the
real code path.

    nice .venv/bin/python bench/prognosis_blind.py [--per-shape 200] [--workers 2] [--seed 4343]
        [--out bench/results/prognosis_blind.json]

The shapes were written by a helper who read only docs/prognosis.md's description of the
outputs; this file only drives them. As in bench/prognosis.py, every fit goes through
``service.alarms.update`` (the fit job's detector) and the prognosis is
``service.prognosis.prognose`` on that state and the fits since the reset, as the worker does,
with the same truth rules:

- a degrading history is asked when it is halfway and three quarters of the way, in operations,
  from its onset (the last operation whose true level is still the baseline) to its true
  crossing; a shape that never crosses (leak_that_stops) at those fractions of the way from its
  onset to the history's end;
- the truth is the first operation whose noise-free level (``true_level``, at the blind file's
  reference temperature: the mean over the detector's baseline window) is past the limit the
  prognosis used; at or before now it is 0 operations ("crossed: service is due"); a path that
  never crosses has the truth "beyond the horizon", which an interval holds when its 95 %
  quantile is beyond it (None);
- a "no trend" prognosis has no median and no 95 % quantile: its interval is [p05, beyond);
- the date interval is judged the same way against the true crossing's time;
- a healthy history is asked at its last operation; "predicted to cross within 10 years" is a
  median within the horizon, compared with the shape's own ``true_crosses_within_10y``.

Writes per-shape coverage of the 90 % interval (operations and dates), the truth below p05 /
above p95, the median relative error at halfway and the healthy shares.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from prognosis_shapes_blind import SHAPES  # noqa: E402

from service.alarms import DriftSettings, DriftState, FitObservation, update  # noqa: E402
from service.breaker_limits import ParameterLimit  # noqa: E402
from service.prognosis import prognose  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "prognosis_blind.json"
FRACTIONS = (0.5, 0.75)
# Shapes whose true slope changes at a few operations (the break, the stop, the refill): a
# question asked before the last change cannot see it. Their coverage is also given over the
# questions asked at least 15 operations after it (the "break >= 15 ops before the question").
KINKED = ("slow_then_fast", "repair_relapse", "leak_that_stops")
AFTER_CHANGE = 15
T0 = datetime(2024, 1, 1, tzinfo=timezone.utc)


def onset_of(level: np.ndarray) -> int:
    """0-based index of the last operation whose true level equals the first one's."""
    moved = np.flatnonzero(np.abs(level - level[0]) > 1e-9 * abs(level[0]))
    return int(moved[0]) - 1 if moved.size else level.size - 1


def last_change(level: np.ndarray, upto: int) -> int | None:
    """0-based index of the last change of the true slope after the onset (the first change) at or
    before ``upto``, None if none."""
    d2 = np.abs(np.diff(level[:upto + 1], 2))
    idx = np.flatnonzero(d2 > 1e-9 * abs(level[0]))
    return int(idx[-1]) + 1 if idx.size > 1 else None


def first_past(level: np.ndarray, bound: float, direction: str) -> int | None:
    """0-based index of the first operation whose level is past ``bound``."""
    past = level <= bound if direction == "falling" else level >= bound
    idx = np.flatnonzero(past)
    return int(idx[0]) if idx.size else None


def one(shape: str, seed: list[int], settings: DriftSettings) -> list[dict]:
    h = SHAPES[shape](np.random.default_rng(seed))
    n = h.times_s.size
    limit = ParameterLimit(min_change=h.limit_change)
    times = [T0 + timedelta(seconds=float(s)) for s in h.times_s]
    obs = [FitObservation(operation_id=i + 1, time=t, value=float(v), ci95=(float(v - c), float(v + c)),
                          temperature=None if h.temperature_c is None else float(h.temperature_c[i]))
           for i, (t, v, c) in enumerate(zip(times, h.observed, h.fit_ci95_halfwidth))]
    if h.degrading:
        onset = onset_of(h.true_level)
        c0 = first_past(h.true_level, h.baseline * (1 + h.limit_change), "falling")
        end = c0 if c0 is not None else n - 1
        # j: fits fed (1-based count), the prognosis's "now" is obs[j - 1]
        stops = sorted({min(n, onset + 1 + max(1, round(fr * (end - onset)))) for fr in FRACTIONS})
        fracs = FRACTIONS[:len(stops)]
    else:
        stops, fracs = [n], [None]
    state, rows, k = DriftState.new(h.parameter, settings), [], 0
    for j, o in enumerate(obs, start=1):
        state, _ = update(state, o, settings)
        if j != stops[k]:
            continue
        t0 = time.perf_counter()
        prog = prognose(state, obs[:j], limit)
        cost = time.perf_counter() - t0
        q, dq = prog.operations_to_limit, prog.date_to_limit
        now = times[j - 1]
        row = {"shape": shape, "parameter": h.parameter, "at": j, "fraction": fracs[k], "status": prog.status,
               "alarm": state.level, "basis": prog.basis, "cost_ms": cost * 1e3, "notes": h.notes,
               "pred": [None, None, None] if q is None else [q.p05, q.median, q.p95],
               "pred_days": [None, None, None] if dq is None else
               [None if d is None else (d - now).total_seconds() / 86400.0 for d in (dq.p05, dq.median, dq.p95)],
               "rate_per_day": prog.rate_per_day}
        if h.degrading:
            truth, truth_days = None, None
            if prog.limit is not None:
                c = first_past(h.true_level, prog.limit, prog.direction)
                if c is not None:
                    truth = max(c + 1 - j, 0)
                    truth_days = max((h.times_s[c] - h.times_s[j - 1]) / 86400.0, 0.0)
                else:
                    truth, truth_days = math.inf, math.inf
            row.update(truth=truth, truth_days=truth_days)
            if shape in KINKED:
                lc = last_change(h.true_level, j - 1)
                row["since_change"] = None if lc is None else j - 1 - lc
        else:
            row["true_crosses_within_10y"] = bool(h.true_crosses_within_10y)
        rows.append(row)
        k += 1
        if k == len(stops):
            break
    return rows


def _job(args):
    shape, seeds, settings_dict = args
    settings = DriftSettings.from_mapping(settings_dict)
    return [r for s in seeds for r in one(shape, s, settings)]


def _covered(pred, truth) -> bool:
    lo, _, hi = pred
    lo, hi = (math.inf if lo is None else lo), (math.inf if hi is None else hi)
    if truth is None:
        return False
    if math.isinf(truth):
        return math.isinf(hi)
    return lo <= truth <= hi


def summarise(rows: list[dict]) -> dict:
    def stats_of(sel):
        if not sel:
            return None
        half = [r for r in sel if r["fraction"] == 0.5]
        cov = [_covered(r["pred"], r["truth"]) for r in sel]
        below = [r["truth"] is not None and r["pred"][0] is not None and r["truth"] < r["pred"][0] for r in sel]
        errs = [abs((r["pred"][1] if r["pred"][1] is not None else math.inf) - r["truth"]) / max(r["truth"], 1)
                for r in half if r["truth"] is not None and math.isfinite(r["truth"])]
        dated = [r for r in sel if r["rate_per_day"] is not None and r["truth_days"] is not None]
        dcov = [_covered(r["pred_days"], r["truth_days"]) for r in dated]
        return {"predictions": len(sel), "coverage_90": round(float(np.mean(cov)), 4),
                "coverage_90_at_half": round(float(np.mean([_covered(r["pred"], r["truth"]) for r in half])), 4)
                if half else None,
                "truth_below_p05": round(float(np.mean(below)), 4),
                "truth_above_p95": round(1 - float(np.mean(below)) - float(np.mean(cov)), 4),
                "median_rel_error_at_half": round(float(np.median(errs)), 4) if errs else None,
                "date_coverage_90": round(float(np.mean(dcov)), 4) if dcov else None,
                "with_alarm": round(float(np.mean([r["alarm"] != "none" for r in sel])), 4)}

    degrading = [r for r in rows if "truth" in r]
    healthy = [r for r in rows if "truth" not in r]
    shapes = sorted({r["shape"] for r in degrading}, key=list(SHAPES).index)
    hshapes = sorted({r["shape"] for r in healthy}, key=list(SHAPES).index)

    def hstats(sel):
        pred = float(np.mean([r["pred"][1] is not None for r in sel]))
        true = float(np.mean([r["true_crosses_within_10y"] for r in sel]))
        return {"breakers": len(sel), "predicted_crossing_within_10_years": round(pred, 4),
                "true_crossing_within_10_years": round(true, 4),
                "target_at_most": round(2 * true + 0.01, 4), "met": pred <= 2 * true + 0.01}

    per = {s: stats_of([r for r in degrading if r["shape"] == s]) for s in shapes}
    for s in shapes:
        if s in KINKED:
            late = [r for r in degrading if r["shape"] == s and (r.get("since_change") or 0) >= AFTER_CHANGE]
            per[s]["asked_15_or_more_after_the_last_change"] = stats_of(late)
    costs = [r["cost_ms"] for r in rows]
    return {"overall": stats_of(degrading), "per_shape": per,
            "healthy": {s: hstats([r for r in healthy if r["shape"] == s]) for s in hshapes},
            "cost_ms_per_prognosis": {"median": round(float(np.median(costs)), 3),
                                      "p99": round(float(np.percentile(costs, 99)), 3)}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-shape", type=int, default=200)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=4343)
    ap.add_argument("--shapes", nargs="*", default=list(SHAPES))
    ap.add_argument("--out", type=Path, default=RESULTS)
    a = ap.parse_args(argv)
    settings = DriftSettings()
    jobs = [(s, [[a.seed, k, b] for b in range(lo, min(a.per_shape, lo + 10))], settings.to_dict())
            for k, s in enumerate(SHAPES) if s in a.shapes for lo in range(0, a.per_shape, 10)]
    load_before = Path("/proc/loadavg").read_text().split()[:3]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(a.workers) as ex:
        rows = [r for chunk in ex.map(_job, jobs) for r in chunk]
    result = {"per_shape_histories": a.per_shape, "seed": a.seed, "workers": a.workers,
              "runtime_s": round(time.perf_counter() - t0, 1),
              "load_average_before_after": [load_before, Path("/proc/loadavg").read_text().split()[:3]],
              **summarise(rows),
              "targets": {"coverage_90_each": [0.80, 0.97], "coverage_90_overall": [0.85, 0.95],
                          "healthy": "<= 2 x true share + 0.01", "date_coverage_bursty": 0.85}}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
