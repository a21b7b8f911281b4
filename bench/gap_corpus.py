"""Write the gap study's corpus once, then diagnose it in resumable chunks (issue 48 item 1).

Run under the heavy-run lock, one chunk (≤ 9 min) at a time, releasing it between chunks:
    flock /tmp/hvcb-heavy.lock nice -n 5 .venv/bin/python bench/gap_corpus.py [--budget 540]
Writes var/gap48/ (captures, corpus.json, oracle.jsonl, rows_{clean,realistic,crank}.jsonl);
prints the counts done and the ``uptime`` into var/gap48/chunks.jsonl. Re-run until nothing is
left. Each written group (5 captures) is diagnosed on its first 3 and on all 5, through the
prototype's own sensor and the two sensor kinds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from service.studies.gap import corpus  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SIZES = {"per_effect": 1, "controls": 3, "two_effect": 2, "outside": 1, "captures_per_group": 5}
SEED = 4848


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "var/gap48")
    ap.add_argument("--budget", type=float, default=540.0)
    ap.add_argument("--prototypes", default="a,b,c,d,e")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    up0 = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    t0 = time.time()
    jobs = corpus.write(args.out, args.prototypes.split(","), seed=SEED, sizes=SIZES)
    done = corpus.run(args.out, budget_s=args.budget, workers=args.workers)
    up1 = subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    rec = {"groups_written": len(jobs), **done, "wall_s": time.time() - t0, "uptime_start": up0, "uptime_end": up1}
    with (args.out / "chunks.jsonl").open("a") as f:
        f.write(json.dumps(rec) + "\n")
    print(json.dumps(rec))
    return done


if __name__ == "__main__":
    main()
