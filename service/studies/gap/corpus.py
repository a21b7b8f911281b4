"""The gap study's corpus, written once and scored without simulating again (issue 42 item 3).

``write``: each prototype's groups (the generator's ``write_groups``: COMTRADE captures, the
clean and healthy curves, the manifest) under ``<out>/<proto>/`` and the list of groups in
``<out>/corpus.json``; done once (a prototype already written is kept).

``run``: diagnoses the groups in chunks, each variant in turn: ``clean`` (the prototype's own
sensor) and ``realistic`` (the same captures read through the shared sensor layer,
``service/prototypes/sensor.py``: one transducer per group, seeded by the group), and the
oracle's Δχ² once per group (from the clean curves: the effect's detectability, the same for
both variants). Rows are appended to ``<out>/rows_<variant>.jsonl`` and ``<out>/oracle.jsonl``
as they finish, and ``run`` stops after ``budget_s``: a stopped run resumes where it was.
Scoring (``risk``) re-reads these files and simulates nothing.
"""

from __future__ import annotations

import json
import time
import zlib
from pathlib import Path

import numpy as np

from .runner import KEEP, write_jobs

VARIANTS = ("clean", "realistic")


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


def _read(out: Path, name: str) -> dict:
    f = out / name
    if not f.exists():
        return {}
    rows = [json.loads(x) for x in f.read_text().splitlines() if x.strip()]
    return {(r["prototype"], r["group"]): r for r in rows}


def _captures(job: dict, variant: str, breaker):
    from ...acquisition.capture_file import read_capture
    from ...prototypes import sensor

    caps = [read_capture(str(Path(job["dir"]) / f"{s}.cfg"), travel_channel=breaker.channels["travel"],
                         vibration_channel=breaker.channels["vibration"]) for s in job["stems"]]
    if variant == "realistic":
        seed = zlib.crc32(f"{job['prototype']}/{job['group']}".encode())
        rng = np.random.default_rng(seed)
        unit = sensor.draw_unit(rng)
        caps = [sensor.apply(c, unit, rng, stroke=breaker.stroke, operation=job["operation"]) for c in caps]
    return caps


def diagnose_job(task) -> dict:
    """One group of one variant, blind (the diagnosis sees only the captures)."""
    from ...diagnosis import diagnose
    from ..common import load_reference

    job, variant = task
    breaker = load_reference()
    row = dict(job, variant=variant)
    t0 = time.perf_counter()
    try:
        r = diagnose(_captures(job, variant, breaker), breaker, job["operation"], next_measurements=False)
        row.update({k: r[k] for k in KEEP if k in r})
        row["holdout_shrink"] = r.get("holdout_shrink")
    except Exception as exc:        # noqa: BLE001 - a study row records any refusal or failure in words
        row["error"] = f"{type(exc).__name__}: {exc}"
    row["diagnose_s"] = time.perf_counter() - t0
    return row


def oracle_job(job) -> dict:
    from ..common import load_reference
    from .oracle import oracle_of_files

    try:
        o = oracle_of_files(job["dir"], job["stems"], load_reference(), job["operation"])
        o.pop("captures", None)
    except (ValueError, FileNotFoundError) as exc:
        o = {"error": str(exc)}
    return {"prototype": job["prototype"], "group": job["group"], "oracle": o}


def _task(task):
    """One group's oracle or one group of one variant (for the pool)."""
    kind, job = task
    return ("oracle", oracle_job(job)) if kind == "oracle" else (kind, diagnose_job((job, kind)))


def run(out, *, budget_s: float = 840.0, workers: int = 2, variants=VARIANTS) -> dict:
    """Diagnose what is not yet on disk, for at most ``budget_s`` [s], the groups in a shuffled
    order and each group's variants and oracle together (a stopped run has sampled every
    prototype and both variants); returns the counts done."""
    from ..common import pool_map

    out = Path(out)
    jobs = json.loads((out / "corpus.json").read_text())["jobs"]
    t0 = time.perf_counter()
    have = {v: _read(out, f"rows_{v}.jsonl") for v in variants}
    oracle = _read(out, "oracle.jsonl")
    tasks = []
    for i in np.random.default_rng(42).permutation(len(jobs)):
        j = jobs[int(i)]
        key = (j["prototype"], j["group"])
        tasks += [("oracle", j)] if key not in oracle else []
        tasks += [(v, j) for v in variants if key not in have[v]]
    for k in range(0, len(tasks), workers):
        if time.perf_counter() - t0 > budget_s:
            break
        for kind, r in pool_map(_task, tasks[k:k + workers], workers):
            name = "oracle.jsonl" if kind == "oracle" else f"rows_{kind}.jsonl"
            with (out / name).open("a") as f:
                f.write(json.dumps(r, default=float) + "\n")
    return {v: len(_read(out, f"rows_{v}.jsonl")) for v in variants} | {"groups": len(jobs),
                                                                         "oracle": len(_read(out, "oracle.jsonl"))}


def rows(out, variant: str) -> list:
    """The variant's rows with their oracle, read back from disk."""
    out = Path(out)
    oracle = _read(out, "oracle.jsonl")
    got = []
    for key, r in _read(out, f"rows_{variant}.jsonl").items():
        r = dict(r)
        r["oracle"] = oracle.get(key, {}).get("oracle", {})
        got.append(r)
    return got
