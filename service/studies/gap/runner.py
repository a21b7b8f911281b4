"""``hvcb study gap``: write each prototype's groups, diagnose every group blind, run the oracle.

Per prototype the generator's ``write_groups`` writes COMTRADE captures, ``<stem>.clean.npy``
(and ``.healthy.npy``) and ``manifest.json`` into ``<out>/<proto>/``. Each group is then
diagnosed from its files alone (the diagnosis sees neither the manifest nor the clean curves;
when it offers effect subspaces built without a prototype, the variant without the scored one
is used: leave-one-prototype-out) and the oracle (:mod:`.oracle`) scores it from the clean
curves. The files are rewritten after each prototype, so a stopped run keeps what it finished.
"""

from __future__ import annotations

import importlib
import inspect
import json
import os
import time
from pathlib import Path

import numpy as np

from .scoring import DEVELOPMENT

DEFAULT_SEED = 2026
SIZES = {"per_effect": 4, "controls": 6, "two_effect": 8, "outside": 2, "captures_per_group": 5}
QUICK = {"per_effect": 1, "controls": 2, "two_effect": 1, "outside": 1, "captures_per_group": 3}
# the argument of ``diagnose`` that selects the effect subspaces built without one prototype
LOPO_ARGUMENT = "without_prototype"
SUBSPACE_ARGUMENT = "prototypes"   # or: the prototypes the subspaces were built from
CHUNK = 3   # groups per worker between two summaries


def generator(p: str):
    """The prototype's group writer: ``service.prototypes.<p>.groups`` or the package itself."""
    try:
        return importlib.import_module(f"service.prototypes.{p}.groups")
    except ModuleNotFoundError:
        mod = importlib.import_module(f"service.prototypes.{p}")
        if not hasattr(mod, "write_groups"):
            raise
        return mod


def available_prototypes(candidates=DEVELOPMENT) -> list:
    out = []
    for p in candidates:
        try:
            generator(p)
            out.append(p)
        except ModuleNotFoundError:
            pass
    return out


def groups_of(d: Path, returned) -> list:
    """The groups of a written manifest (a dict with ``groups`` or a plain list)."""
    data = json.loads((d / "manifest.json").read_text()) if (d / "manifest.json").exists() else returned
    return data["groups"] if isinstance(data, dict) else data


KEEP = ("status", "effects", "answer", "answer_probability", "raw_probability", "probabilities", "rivals",
        "absorbed", "gap", "materiality", "discrepancy", "blocks", "noise_model", "evidence", "stages_s")


def diagnose_group(job: dict) -> dict:
    """Diagnose one group from its files (blind), then run the oracle on it."""
    from ...acquisition.capture_file import read_capture
    from ...diagnosis import DiagnosisError, diagnose
    from ..common import load_reference
    from .oracle import oracle_of_files

    breaker = load_reference()
    row = dict(job)
    caps = [read_capture(str(Path(job["dir"]) / f"{s}.cfg"), travel_channel=breaker.channels["travel"],
                         vibration_channel=breaker.channels["vibration"]) for s in job["stems"]]
    kwargs = {}
    accepted = inspect.signature(diagnose).parameters
    if LOPO_ARGUMENT in accepted:
        kwargs[LOPO_ARGUMENT] = job["prototype"]
    elif SUBSPACE_ARGUMENT in accepted and job["prototype"] in DEVELOPMENT:
        kwargs[SUBSPACE_ARGUMENT] = tuple(q for q in DEVELOPMENT if q != job["prototype"])
    row["lopo_subspaces"] = bool(kwargs)
    t0 = time.perf_counter()
    try:
        r = diagnose(caps, breaker, job["operation"], next_measurements=False, **kwargs)
        row.update({k: r[k] for k in KEEP if k in r})
    except DiagnosisError as exc:
        row["error"] = str(exc)
    row["diagnose_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    try:
        o = oracle_of_files(job["dir"], job["stems"], breaker, job["operation"])
        o.pop("captures")
        row["oracle"] = o
    except (ValueError, FileNotFoundError) as exc:
        row["oracle"] = {"error": str(exc)}
    row["oracle_s"] = time.perf_counter() - t0
    return row


def write_jobs(out: Path, p: str, seed: int, sizes: dict) -> list:
    d = out / p
    returned = generator(p).write_groups(d, seed=seed, **sizes)
    jobs = []
    for g in groups_of(d, returned):
        outside = bool(g["outside_catalogue"])
        jobs.append({"prototype": p, "dir": str(d), "group": g.get("group", g.get("id")),
                     "operation": g["operation"], "truth": [] if outside else sorted(g["effects"]),
                     "outside": outside, "strengths": g["effects"], "stems": g["stems"]})
    return jobs


def run_gap_study(out_dir: Path, *, seed: int = DEFAULT_SEED, quick: bool = False, workers: int = 2,
                  prototypes=None, sizes=None, ship_calibration: bool = False, with_rows=None,
                  resume: bool = True) -> dict:
    """Write the groups of every prototype, diagnose them and run the oracle (a pool of
    ``workers``), score.

    The groups of all prototypes are diagnosed in one shuffled order and the summary is
    rewritten every few groups, so a run stopped early has scored a sample of every prototype
    and kind of group. ``resume``: groups already in ``out_dir``'s ``gap_groups.json`` from a run
    of the same seed and sizes are not diagnosed again. ``ship_calibration``: also write the map
    fitted on the development prototypes to ``service/diagnosis/calibration.json`` when the run
    completes. ``with_rows``: the ``gap_groups.json`` of an earlier run whose rows are scored
    alongside (a held-out prototype run alone is then calibrated by the development prototypes'
    map)."""
    from ..common import pool_map
    from .report import summarise

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sizes = dict(sizes or (QUICK if quick else SIZES))
    protos = list(prototypes or available_prototypes())
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    t0 = time.perf_counter()
    rows = []
    saved = out / "gap_groups.json"
    if resume and saved.exists():
        prev = json.loads(saved.read_text())
        if prev.get("seed") == seed and prev.get("sizes") == sizes:
            rows = [r for r in prev["rows"] if r["prototype"] in protos]
    jobs = []
    for p in protos:
        jobs += [j for j in write_jobs(out, p, seed, sizes)
                 if not any(r["prototype"] == p and r["group"] == j["group"] for r in rows)]
    if with_rows is not None:
        earlier = json.loads(Path(with_rows).read_text())
        rows += [r for r in earlier["rows"] if r["prototype"] not in protos]
        protos = [p for p in earlier["prototypes"] if p not in protos] + protos
    jobs = [jobs[int(i)] for i in np.random.default_rng([seed, 29]).permutation(len(jobs))]
    step = CHUNK * max(1, int(workers))
    meta = {"seed": seed, "quick": quick, "sizes": sizes, "prototypes": protos, "workers": workers}
    result = summarise(out, rows, {**meta, "complete": not jobs}) if rows else None
    for k in range(0, len(jobs), step):
        rows += pool_map(diagnose_group, jobs[k:k + step], max(1, int(workers)))
        last = k + step >= len(jobs)
        result = summarise(out, rows, {**meta, "wall_s": time.perf_counter() - t0, "complete": last,
                                       "groups_done": {q: sum(r["prototype"] == q for r in rows) for q in protos}},
                           ship_calibration=ship_calibration and last)
    return result


def rescore(out_dir, ship_calibration: bool = False) -> dict:
    """Score an earlier run again from its saved rows (nothing is diagnosed again)."""
    from .report import summarise

    out = Path(out_dir)
    g = json.loads((out / "gap_groups.json").read_text())
    meta = {k: g.get(k) for k in ("seed", "quick", "sizes", "prototypes", "workers", "wall_s", "complete", "groups_done")}
    return summarise(out, g["rows"], meta, ship_calibration=ship_calibration)
