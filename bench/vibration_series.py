"""Issue 49's withheld-series check: the latch time through the drift detector over whole breaker
histories, on both trip generators (bench/vibration_events.py names them), with seeds the detector
was never run on while it was written.

Series (60 openings each, per generator):
- ``healthy``: latch time 1.2 ms with 2 % run-to-run spread, strike 30 g: nothing may be raised;
- ``growing``: the same, then from opening 30 the latch sticks 0.02 ms more each opening: the
  alarm must come within 15 openings of the start;
- ``quiet``: a healthy latch whose strike is only 3–5x the 0.6 g noise: every latch time within
  0.3 ms of the truth (median error <= 0.1 ms) or None with its reason.

Each opening's latch time is read by ``service.vibration`` from the start of motion (the truth's,
or with ``--fit`` the travel fit's own onset, as the service does), checked against the breaker's
fingerprint (its first 10 openings: a first shock where the release is means a missed strike), and
fed to the self-starting CUSUM of ``service.alarms`` (``observations_from_fit``, ``replay``) with
the shipped settings (config/default.toml's ``[alarms]``: ``latch_time_s`` watched rising beside
DO and BO, its thresholds designed for the 4 sides together; ``--by-hand`` watches the latch alone,
as issue 49's study did). Writes bench/results/vibration_series.json (with ``uptime``).
Run: PYTHONPATH=. .venv/bin/python bench/vibration_series.py [--fit] [--seed N] [--only growing,quiet]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from vibration_events import GENERATORS, NOISE_G  # noqa: E402

from service.alarms import observations_from_fit, replay  # noqa: E402
from service.alarms.settings import DriftSettings  # noqa: E402
from service.breaker_file import load_breaker  # noqa: E402
from service.estimation.fit import fit_capture  # noqa: E402
from service.vibration import Fingerprint, vibration_characteristics  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OPENINGS = 60
HEALTHY_S = 1.2e-3
SPREAD_REL = 0.02
GROW_FROM = 30
GROW_PER_OPENING_S = 0.02e-3
ALARM_WITHIN = 15
FINGERPRINT_OPENINGS = 10
T0 = datetime(2026, 1, 1, tzinfo=timezone.utc)


def latch_truth(kind: str, i: int, rng) -> float:
    lt = HEALTHY_S * (1.0 + SPREAD_REL * rng.standard_normal())
    if kind == "growing" and i >= GROW_FROM:
        lt += (i - GROW_FROM + 1) * GROW_PER_OPENING_S
    return lt


def shipped_settings() -> DriftSettings:
    """The drift settings ``hvcb serve`` runs with by default (config/default.toml)."""
    from service.settings import load_settings

    return load_settings(ROOT / "config/default.toml").drift_settings


def series(breaker, gen: str, kind: str, seed: int, use_fit: bool, settings: DriftSettings):
    rng = np.random.default_rng([seed, len(gen), len(kind)])
    make = GENERATORS[gen]
    chars, truths = [], []
    for i in range(OPENINGS):
        lt = latch_truth(kind, i, rng)
        strike = float(rng.uniform(3, 5)) * NOISE_G if kind == "quiet" else 30.0
        cap, t_motion, t_end = make(breaker, rng, lt, strike)
        if use_fit:
            ch = fit_capture(cap, breaker, "open").characteristics
        else:
            ch = vibration_characteristics(cap, "open", t_motion, t_end)
        chars.append(ch)
        truths.append(lt)
    fp = Fingerprint("open").fit(chars[:FINGERPRINT_OPENINGS])
    checked = []
    for ch in chars:
        missed = fp.shift(ch)["strike_not_seen"] if ch.get("latch_time_s") is not None else None
        checked.append({**ch, "latch_time_s": None, "latch_time_reason": missed} if missed else ch)
    obs = []
    for i, ch in enumerate(checked):
        o = observations_from_fit({"parameters": {}, "characteristics": ch}, operation_id=i,
                                  time=T0 + timedelta(hours=i), settings=settings).get("latch_time_s")
        if o is not None:
            obs.append(o)
    _, events = replay(obs, settings, parameter="latch_time_s")
    raised = [e for e in events if e.kind in ("raised", "escalated")]
    errors = [c["latch_time_s"] - t for c, t in zip(checked, truths) if c.get("latch_time_s") is not None]
    e = np.abs(errors)
    first_alarm = next((ev.operation_id for ev in raised if ev.level == "alarm"), None)
    first_any = raised[0].operation_id if raised else None
    reasons = {}
    for c in checked:
        if c.get("latch_time_s") is None:
            key = (c.get("latch_time_reason") or "?").split(":")[0][:70]
            reasons[key] = reasons.get(key, 0) + 1
    row = {"generator": gen, "series": kind, "openings": OPENINGS, "timed": int(e.size),
           "null": OPENINGS - int(e.size), "null_reasons": reasons,
           "outside_0_3_ms": int(np.sum(e > 0.3e-3)), "median_abs_error_ms": float(np.median(e) * 1e3) if e.size else None,
           "max_abs_error_ms": float(e.max() * 1e3) if e.size else None,
           "raised": [{"level": ev.level, "operation": ev.operation_id} for ev in raised],
           "first_warning_or_alarm_opening": first_any, "first_alarm_opening": first_alarm}
    if kind == "healthy":
        row["pass"] = not raised and row["outside_0_3_ms"] == 0
    elif kind == "growing":
        row["openings_to_alarm"] = None if first_alarm is None else first_alarm - GROW_FROM + 1
        row["pass"] = (first_alarm is not None and GROW_FROM <= first_alarm < GROW_FROM + ALARM_WITHIN
                       and not [ev for ev in raised if ev.operation_id < GROW_FROM])
    else:
        row["pass"] = row["outside_0_3_ms"] == 0 and (row["median_abs_error_ms"] or 0.0) <= 0.1
    print(f"{gen:5} {kind:8}: {row['timed']} timed, {row['null']} null, {row['outside_0_3_ms']} outside 0.3 ms, "
          f"median {row['median_abs_error_ms']}, raised {row['raised'][:3]} -> {'PASS' if row['pass'] else 'FAIL'}",
          flush=True)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fit", action="store_true", help="the start of motion from the travel fit (slow)")
    ap.add_argument("--seed", type=int, default=2049)
    ap.add_argument("--only", default="healthy,growing,quiet", help="series to run, comma-separated")
    ap.add_argument("--out", default=None)
    ap.add_argument("--by-hand", action="store_true", help="the latch watched alone (issue 49's study)")
    args = ap.parse_args()
    out = Path(args.out or ROOT / f"bench/results/vibration_series{'_fit' if args.fit else ''}"
                                  f"{'_by_hand' if args.by_hand else ''}.json")
    settings = DriftSettings(watched={"latch_time_s": "rising"}) if args.by_hand else shipped_settings()
    result_only = args.only
    breaker = load_breaker(ROOT / "config/breakers/reference-252kV.toml")
    t0 = time.perf_counter()
    result = {"uptime_before": subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip(),
              "motion_from": "travel fit onset" if args.fit else "simulated truth",
              "settings": "the latch watched alone" if args.by_hand else "shipped (config/default.toml)",
              "watched": dict(settings.watched),
              "thresholds": {"k": settings.k, "h_warning": settings.h_warning, "h_alarm": settings.h_alarm},
              "seed": args.seed, "series": result_only, "rows": [series(breaker, g, k, args.seed, args.fit, settings)
                                          for g in GENERATORS for k in args.only.split(",")]}
    result["all_pass"] = all(r["pass"] for r in result["rows"])
    result["wall_s"] = time.perf_counter() - t0
    result["uptime_after"] = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {out} ({result['wall_s']:.0f} s); all pass: {result['all_pass']}")


if __name__ == "__main__":
    main()
