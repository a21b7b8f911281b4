"""Write the gap study's corpus once, then diagnose it in resumable chunks (issue 42 item 3).

Run under the heavy-run lock, one chunk (≤ 14 min) at a time:
    flock /tmp/hvcb-heavy.lock nice -n 5 .venv/bin/python bench/gap_corpus.py [--budget 840]
Writes var/gap_corpus/ (captures, corpus.json, oracle.jsonl, rows_clean.jsonl,
rows_realistic.jsonl); prints the counts done. Re-run until every group of both variants is done.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from service.studies.gap import corpus  # noqa: E402
from service.studies.gap.runner import QUICK  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "var/gap_corpus")
    ap.add_argument("--budget", type=float, default=840.0)
    ap.add_argument("--prototypes", default="a,b,c,d,e")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)
    sizes = dict(QUICK)
    jobs = corpus.write(args.out, args.prototypes.split(","), seed=args.seed, sizes=sizes)
    print(f"{len(jobs)} groups written ({sizes})")
    done = corpus.run(args.out, budget_s=args.budget, workers=args.workers)
    print(json.dumps(done))
    return done


if __name__ == "__main__":
    main()
