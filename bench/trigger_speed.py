"""Trigger detector speed and memory on a long scripted stream (issue 3: ≥ 100× real time).

Runs on one core. The stream (default 10 min at 128 kHz, an operation every second, lone shocks
and noise bursts) is generated lazily block by block; only the time spent inside the detector is
counted, as CPU time of this process (the speed figure) and as wall time. Prints the figures and writes ``bench/results/trigger_speed.json``.

    .venv/bin/python bench/trigger_speed.py [--minutes 10] [--block-samples 4096] [--return-shape model|critical|oscillating]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core: no threaded BLAS behind numpy
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def peak_rss_mb() -> float:
    """Peak resident set size of this process [MB] (ru_maxrss is in kB on Linux)."""
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="stream length [min]")
    parser.add_argument("--block-samples", type=int, default=4096, help="samples per block")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--return-shape", choices=("model", "critical", "oscillating"), default="model",
                        help="how openings return from overtravel to rest")
    parser.add_argument("--out", default=str(ROOT / "bench" / "results" / "trigger_speed.json"))
    args = parser.parse_args(argv)

    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})

    from drivers.stream_script import LoneShock, NoiseBurst, ScriptedStream
    from service.acquisition.trigger import TriggerDetector, TriggerSettings
    from service.breaker_file import load_breaker

    breaker = load_breaker(ROOT / "config" / "breakers" / "reference-252kV.toml")
    duration = 60.0 * args.minutes
    shocks = [LoneShock(t + 0.55, 300.0) for t in range(0, int(duration) - 1, 7)]
    bursts = [NoiseBurst(t + 0.75, 0.05) for t in range(0, int(duration) - 1, 13)]
    stream = ScriptedStream(breaker, duration_s=duration, seed=args.seed, spacing_s=1.0,
                            shocks=shocks, bursts=bursts, return_shape=args.return_shape)
    detector = TriggerDetector(TriggerSettings.from_breaker(breaker), stream.fs)

    busy = 0.0  # detector CPU time on this one core [s]; immune to other load on the machine
    busy_wall = 0.0
    found = 0
    rss_after_first_minute = None
    wall0 = time.perf_counter()
    for block in stream.blocks(args.block_samples):
        c0, t0 = time.process_time(), time.perf_counter()
        found += len(detector.feed(block))
        busy += time.process_time() - c0
        busy_wall += time.perf_counter() - t0
        if rss_after_first_minute is None and block.end_index >= 60 * stream.fs:
            rss_after_first_minute = peak_rss_mb()
    c0, t0 = time.process_time(), time.perf_counter()
    found += len(detector.flush())
    busy += time.process_time() - c0
    busy_wall += time.perf_counter() - t0
    wall = time.perf_counter() - wall0

    result = {
        "stream_s": duration,
        "sample_rate_hz": stream.fs,
        "block_samples": args.block_samples,
        "operations_scripted": len(stream.truth),
        "operations_detected": found,
        "lone_shocks": len(shocks),
        "noise_bursts": len(bursts),
        "return_shape": args.return_shape,
        "detector_cpu_s": round(busy, 3),
        "detector_wall_s": round(busy_wall, 3),
        "speed_x_real_time": round(duration / busy, 1),
        "speed_x_real_time_wall": round(duration / busy_wall, 1),
        "samples_per_s": round(stream.n_samples / busy),
        "wall_s_including_generation": round(wall, 2),
        "peak_rss_mb": round(peak_rss_mb(), 1),
        "peak_rss_mb_after_first_minute": round(rss_after_first_minute or 0.0, 1),
        "ring_buffer_samples": detector.buffer_samples,
        "cores": 1,
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1) + "\n")
    print(f"trigger: {duration:.0f} s of 2-channel {stream.fs / 1e3:.0f} kHz stream in {busy:.2f} s "
          f"of detector CPU time = {result['speed_x_real_time']}x real time (one core, "
          f"{args.block_samples}-sample blocks; {result['speed_x_real_time_wall']}x by wall clock)")
    print(f"operations: {found} detected / {len(stream.truth)} scripted "
          f"({len(shocks)} lone shocks, {len(bursts)} noise bursts)")
    print(f"peak RSS {result['peak_rss_mb']} MB (after the first minute {result['peak_rss_mb_after_first_minute']} MB); "
          f"ring buffer {detector.buffer_samples} samples")
    print(f"wrote {out}")
    return 0 if found == len(stream.truth) else 1


if __name__ == "__main__":
    sys.exit(main())
