"""Benchmark: build the default prototype-B dataset (206 captures) on one core.

Prints the CPU and wall time per capture and in total, and writes
bench/results/prototype_b_dataset.json. Run: .venv/bin/python bench/prototype_b_dataset.py
"""

from __future__ import annotations

import json
import os
import platform
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from service.prototypes.b import write_dataset  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        cpu0, wall0 = time.process_time(), time.perf_counter()
        manifest = write_dataset(tmp, seed=2026)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        size = sum(f.stat().st_size for f in Path(tmp).iterdir())
    out = {"machine": platform.processor() or platform.machine(), "python": platform.python_version(),
           "captures": len(manifest), "cpu_s": round(cpu, 2), "wall_s": round(wall, 2),
           "cpu_per_capture_s": round(cpu / len(manifest), 4), "bytes": size}
    print(f"{len(manifest)} captures: {cpu:.1f} s CPU ({cpu / len(manifest) * 1e3:.0f} ms each), "
          f"{wall:.1f} s wall, {size / 1e6:.1f} MB")
    (ROOT / "bench" / "results").mkdir(exist_ok=True)
    (ROOT / "bench" / "results" / "prototype_b_dataset.json").write_text(json.dumps(out, indent=1) + "\n")
    return out


if __name__ == "__main__":
    main()
