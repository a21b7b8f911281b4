"""How long every ``hvcb COMMAND --help`` takes to answer, and how long loading the settings takes
(issue 44 item 4: each <= 0.5 s). Each is a fresh interpreter, run ``--repeat`` times after one
warm-up run (the file cache warm, as for a user's second command); the median and the worst are
written to bench/results/cli_start.json with the machine's load.

    flock /tmp/hvcb-heavy.lock nice -n 5 .venv/bin/python bench/cli_start.py
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from service.cli import COMMANDS  # noqa: E402  (the list of commands; imports nothing heavy)

TARGET_S = 0.5


def timed(argv: list[str]) -> tuple[float, int]:
    t0 = time.perf_counter()
    done = subprocess.run(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return time.perf_counter() - t0, done.returncode


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "cli_start.json"))
    args = ap.parse_args()
    runs = {f"hvcb {c} --help": [sys.executable, "-m", "service.cli", c, "--help"] for c in COMMANDS}
    runs["hvcb --help"] = [sys.executable, "-m", "service.cli", "--help"]
    runs["load_settings()"] = [sys.executable, "-c", "from service.settings import load_settings; load_settings()"]
    runs["python -c pass (the interpreter alone)"] = [sys.executable, "-c", "pass"]
    out = {"uptime": os.popen("uptime").read().strip(), "repeat": args.repeat, "target_s": TARGET_S, "runs": {}}
    for name, argv in runs.items():
        timed(argv)  # warm-up
        times, codes = zip(*(timed(argv) for _ in range(args.repeat)))
        row = {"median_s": round(statistics.median(times), 3), "max_s": round(max(times), 3),
               "exit_codes": sorted(set(codes))}
        out["runs"][name] = row
        print(f"{name:<48} median {row['median_s']:.3f} s  max {row['max_s']:.3f} s  exit {row['exit_codes']}")
    worst = max(v["median_s"] for k, v in out["runs"].items() if k.startswith("hvcb"))
    out["worst_help_median_s"] = worst
    out["all_within_target"] = all(v["max_s"] <= TARGET_S for k, v in out["runs"].items() if k.startswith("hvcb"))
    out["uptime_after"] = os.popen("uptime").read().strip()
    Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"worst median {worst:.3f} s (target {TARGET_S} s); written {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
