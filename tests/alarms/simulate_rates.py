"""Measure the acceptance rates of the drift detector with the real code (not collected by pytest).

    .venv/bin/python tests/alarms/simulate_rates.py --seeds 5000

Prints, per parameter and history kind, the fraction of histories whose alarm (and warning)
rose before operation 31, within 31..40, later, or never, and the detection delay. The numbers in
docs/alarms.md come from this script.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from histories import BO_NOMINAL, DO_NOMINAL, first_alarm, fit_history  # noqa: E402

from service.alarms import DriftSettings, replay  # noqa: E402

CASES = (("DO", DO_NOMINAL, 0.0), ("DO", DO_NOMINAL, -0.01),
         ("BO", BO_NOMINAL, 0.0), ("BO", BO_NOMINAL, -0.01), ("BO", BO_NOMINAL, +0.01))


def classify(op: int | None) -> str:
    if op is None:
        return "never"
    return "before31" if op <= 30 else "31..40" if op <= 40 else "after40"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=2000)
    parser.add_argument("--first-seed", type=int, default=10_000)  # disjoint from the tests
    args = parser.parse_args(argv)
    settings = DriftSettings()
    print(f"settings: {settings.to_dict()}")
    for case, (name, nominal, slope) in enumerate(CASES):
        alarm, warning, delays = Counter(), Counter(), []
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            # Each case its own seeds: BO and DO histories must not be copies of each other.
            _, events = replay(fit_history(seed + 1_000_000 * case, nominal=nominal, slope=slope), settings,
                               parameter=name)
            op_a, op_w = first_alarm(events, "alarm"), first_alarm(events, "warning")
            alarm[classify(op_a)] += 1
            warning[classify(op_w)] += 1
            if slope and op_a is not None and op_a > 30:
                delays.append(op_a - 30)
        n = args.seeds
        fmt = lambda c: ", ".join(f"{k} {v / n:.4%}" for k, v in sorted(c.items()))  # noqa: E731
        print(f"{name} slope {slope:+.0%}/op: alarm [{fmt(alarm)}]  warning [{fmt(warning)}]")
        if delays:
            d = np.array(delays)
            print(f"    alarm delay after op 30 [ops]: median {np.median(d):.0f}, "
                  f"p95 {np.percentile(d, 95):.0f}, max {d.max()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
