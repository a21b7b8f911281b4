"""The gap study's corpus, written once and scored without simulating again (issue 42 item 3).

``write``: each prototype's groups (the generator's ``write_groups``: COMTRADE captures, the
clean and healthy curves, the manifest) under ``<out>/<proto>/`` and the list of groups in
``<out>/corpus.json``; done once (a prototype already written is kept).

``run``: diagnoses the groups in chunks, each variant in turn: ``clean`` (the prototype's own
sensor), ``realistic`` (the same captures read through the lever-driven rotary transducer,
``service/prototypes/sensor.py``) and ``crank`` (through a linear transducer on a crank and a
compliant coupling, ``service/prototypes/sensor_crank.py``), one transducer per group seeded by
the group; each group on its first 3 captures and on all 5 (issue 48: groups of 3–5); the
oracle's Δχ² once per group (from the clean curves; a subset's is the sum of its captures'),
and for the sensor variants the Δχ² of the sensor's bow (``labels``). Each row keeps every
hypothesis's features (``diagnosis.features``). Rows are appended to
``<out>/rows_<variant>.jsonl`` and ``<out>/oracle.jsonl`` as they finish, and ``run`` stops
after ``budget_s``: a stopped run resumes where it was. ``rows`` reads them back with their
label (``labels.label``) and simulates nothing.
"""

from __future__ import annotations

import json
import time
import zlib
from pathlib import Path

import numpy as np

from .runner import KEEP, write_jobs

VARIANTS = ("clean", "realistic", "crank")
SIZES_N = (3, 5)       # each written group of 5 captures is diagnosed on its first 3 and on all 5


def write(out, prototypes, *, seed: int, sizes: dict) -> list:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    index = out / "corpus.json"
    have = json.loads(index.read_text()) if index.exists() else {"seed": seed, "sizes": sizes, "jobs": []}
    done = {j["prototype"] for j in have["jobs"]}
    for p in prototypes:
        if p not in done:
            have["jobs"] += write_jobs(out, p, seed, sizes)
            index.write_text(json.dumps(have, indent=1))
    return have["jobs"]


def _key(r) -> tuple:
    return (r["prototype"], r["group"], int(r.get("n", 0)))


def _read(out: Path, name: str) -> dict:
    f = out / name
    if not f.exists():
        return {}
    rows = [json.loads(x) for x in f.read_text().splitlines() if x.strip()]
    return {_key(r): r for r in rows}


def _sensor(variant: str):
    from ...prototypes import sensor, sensor_crank

    return {"realistic": sensor, "crank": sensor_crank}[variant]


def _captures(job: dict, variant: str, breaker, n: int):
    """The group's first ``n`` captures as the variant reads them, and (sensor variants) the
    Δχ² of the sensor's bow (``labels.bow_delta_chi2``)."""
    from ...acquisition.capture_file import read_capture
    from .labels import bow_delta_chi2

    stems = job["stems"][:n]
    caps = [read_capture(str(Path(job["dir"]) / f"{s}.cfg"), travel_channel=breaker.channels["travel"],
                         vibration_channel=breaker.channels["vibration"]) for s in stems]
    if variant == "clean":
        return caps, None
    mod = _sensor(variant)
    seed = zlib.crc32(f"{variant}/{job['prototype']}/{job['group']}".encode())
    rng = np.random.default_rng(seed)
    unit = mod.draw_unit(rng)
    read = [mod.apply(c, unit, rng, stroke=breaker.stroke, operation=job["operation"]) for c in caps]
    cleans = [np.load(Path(job["dir"]) / f"{s}.clean.npy") for s in stems]
    bow = bow_delta_chi2([c.travel for c in read], cleans, [c.sample_rate for c in read],
                         [c.meta["sensor"] for c in read], mod.reading)
    return read, bow


def diagnose_job(task) -> dict:
    """One group of one variant on its first ``n`` captures, blind (the diagnosis sees only the
    captures). A refusal or a failure is a row with its reason (``error``, ``failed``)."""
    from ...diagnosis import DiagnosisError, diagnose
    from ..common import load_reference

    job, variant, n = task
    breaker = load_reference()
    row = dict(job, variant=variant, n=n)
    t0 = time.perf_counter()
    caps, row["bow_delta_chi2"] = _captures(job, variant, breaker, n)
    try:
        r = diagnose(caps, breaker, job["operation"], next_measurements=False, features_only=True)
    except DiagnosisError as exc:
        row["error"] = str(exc)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError, RuntimeError) as exc:
        row["failed"] = f"{type(exc).__name__}: {exc}"
    else:
        row.update({k: r[k] for k in KEEP if k in r})
        row["holdout_shrink"] = r.get("holdout_shrink")
        row["features"] = r.get("features")
        row["none_test"] = r.get("none_test")      # its df sets the row's detectability threshold (labels)
    row["diagnose_s"] = time.perf_counter() - t0
    return row


def oracle_job(job) -> dict:
    from ..common import load_reference
    from .oracle import oracle_of_files

    try:
        o = oracle_of_files(job["dir"], job["stems"], load_reference(), job["operation"])
        per = o.pop("captures", [])
        o["per_capture_delta"] = [c["delta_chi2"] for c in per]
        o["per_capture_healthy_delta"] = [c.get("healthy_delta_chi2") for c in per]
    except (ValueError, FileNotFoundError) as exc:
        o = {"error": str(exc)}
    return {"prototype": job["prototype"], "group": job["group"], "n": 0, "oracle": o}


def _task(task):
    """One group's oracle or one group of one variant and size (for the pool)."""
    import os

    os.environ["HVCB_DIAGNOSIS_THREADS"] = "1"     # one diagnosis per process on each core
    kind, job, n = task
    return ("oracle", oracle_job(job)) if kind == "oracle" else (kind, diagnose_job((job, kind, n)))


def run(out, *, budget_s: float = 540.0, workers: int = 2, variants=VARIANTS, sizes=SIZES_N) -> dict:
    """Diagnose what is not yet on disk, for at most ``budget_s`` [s], the groups in a shuffled
    order and each group's oracle, variants and sizes together (a stopped run has sampled every
    prototype, variant and size); returns the counts done."""
    from concurrent.futures import FIRST_COMPLETED, wait

    from ...processes import process_pool

    out = Path(out)
    jobs = json.loads((out / "corpus.json").read_text())["jobs"]
    t0 = time.perf_counter()
    have = {v: _read(out, f"rows_{v}.jsonl") for v in variants}
    oracle = {(k[0], k[1]) for k in _read(out, "oracle.jsonl")}
    tasks = []
    order = [jobs[int(i)] for i in np.random.default_rng(42).permutation(len(jobs))]
    for n in sizes:          # every group on its first captures before any on all of them
        for j in order:
            key = (j["prototype"], j["group"])
            if n == sizes[0] and key not in oracle:
                tasks.append(("oracle", j, 0))
            tasks += [(v, j, n) for v in variants if (*key, n) not in have[v]]
    # one pool for the chunk, ``workers`` tasks in flight; no new task after ``budget_s``
    started = 0
    with process_pool(max(1, workers), start_method=None) as ex:
        running = set()
        while running or (started < len(tasks) and time.perf_counter() - t0 <= budget_s):
            while len(running) < workers and started < len(tasks) and time.perf_counter() - t0 <= budget_s:
                running.add(ex.submit(_task, tasks[started]))
                started += 1
            done, running = wait(running, return_when=FIRST_COMPLETED)
            for fut in done:
                kind, r = fut.result()
                name = "oracle.jsonl" if kind == "oracle" else f"rows_{kind}.jsonl"
                with (out / name).open("a") as f:
                    f.write(json.dumps(r, default=float) + "\n")
    return {v: len(_read(out, f"rows_{v}.jsonl")) for v in variants} | {"groups": len(jobs),
                                                                         "oracle": len(_read(out, "oracle.jsonl")),
                                                                         "left": len(tasks) - started}


def rows(out, variant: str) -> list:
    """The variant's rows with their oracle, read back from disk."""
    out = Path(out)
    from .labels import label

    oracle = {(k[0], k[1]): v for k, v in _read(out, "oracle.jsonl").items()}
    got = []
    for key, r in _read(out, f"rows_{variant}.jsonl").items():
        r = dict(r)
        o = dict(oracle.get(key[:2], {}).get("oracle", {}))
        n = int(r.get("n", 0))
        if o.get("per_capture_delta") and n:
            o["delta_chi2_subset"] = float(sum(o["per_capture_delta"][:n]))
            hd = o.get("per_capture_healthy_delta") or []
            if hd and all(x is not None for x in hd[:n]):
                o["healthy_delta_chi2_subset"] = float(sum(hd[:n]))
            o["failed_fits"] = [j for j in o.get("failed_fits", []) if j < n]
        r["oracle"] = o
        r["label"], r["label_reason"] = label(r)
        got.append(r)
    return got
