"""Beyond the paper: how each classifier's accuracy falls as the travel noise rises
(SNR 50 → 30 dB) and as the virtual prototype's effects are turned up.

Each scenario is the Table 9 dataset regenerated with one change (12 captures per condition,
same seeds, so the baseline row reuses the main dataset's first 12 captures), refitted, and
cross-validated with the same folds procedure. It runs on the clean set of issue 5
(:func:`clean_spec`), not on the field set of ``hvcb study classify``:
``service.studies.robustness.run(out_dir)`` writes it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from .classification_methods import METHODS, clean_spec, compare_methods
from .common import DEFAULT_WORKERS
from .condition_data import DatasetSpec, build_dataset, noise_for_snr, snr_db
from .report import write_json, write_markdown

DEFAULT_SEED = 2026


def scenarios(spec: DatasetSpec, quick: bool = False) -> list[tuple[str, DatasetSpec]]:
    """(label, dataset spec) of each robustness row; the first is the unchanged baseline."""
    per = spec.per_condition if quick else 12
    base = dataclasses.replace(spec, per_condition=per)
    rows = [("baseline", base)]
    snrs = (30.0,) if quick else (50.0, 40.0, 30.0)
    for snr in snrs:
        rows.append((f"SNR {snr:.0f} dB", dataclasses.replace(base, noise_rad=noise_for_snr(snr, base))))
    if not quick:
        rows.append(("onset jitter ±0.5 ms", dataclasses.replace(base, onset_jitter_s=0.5e-3)))
    for factor in (() if quick else (1.5, 2.0)):
        rows.append((f"effects ×{factor:g} (REALISTIC ×{base.effects_scale * factor:g})",
                     dataclasses.replace(base, effects_scale=base.effects_scale * factor)))
    return rows


def _subset(data: dict, per: int) -> dict:
    keep = data["index"] < per
    return {k: (v[keep] if k != "names" else v) for k, v in data.items()}


def robustness_table(out_dir: Path, spec: DatasetSpec, data: dict | None = None, *, seed: int,
                     quick: bool = False, workers: int = DEFAULT_WORKERS) -> dict:
    """Accuracy of every method per scenario; writes ``robustness.json`` and ``robustness.md``.

    Parameters
    ----------
    out_dir : Path
    spec : DatasetSpec
        The main (Table 9) dataset.
    data : dict, optional
        Its fitted arrays, to reuse for the baseline row without refitting.
    """

    rows = {}
    for label, s in scenarios(spec, quick):
        if label == "baseline" and data is not None:
            d = _subset(data, s.per_condition)
        else:
            d = build_dataset(s, out_dir, workers=workers)
        cmp = compare_methods(d, seed=seed, quick=quick)
        rows[label] = {
            "snr_db": snr_db(s.noise_rad, s), "noise_rad": s.noise_rad, "effects_scale": s.effects_scale,
            "samples": int(d["condition"].size), "fit_failures": cmp["fit_failures"],
            "median_rmse_rad": float(np.nanmedian(d["rmse_rad"])) if np.any(np.isfinite(d["rmse_rad"])) else None,
            "accuracy": {m: r["mean"] for m, r in cmp["methods"].items()},
            "accuracy_sd": {m: r["sd"] for m, r in cmp["methods"].items()},
            "skipped": cmp["skipped"],
        }
    table = [[label, r["snr_db"], r["effects_scale"], f"{r['fit_failures']}/{r['samples']}"]
             + [None if m not in r["accuracy"] else
                f"{100 * r['accuracy'][m]:.1f} ± {100 * r['accuracy_sd'][m]:.1f}" for m in METHODS]
             for label, r in rows.items()]
    write_markdown(out_dir, "robustness", "Robustness of the condition classifiers (beyond the paper)",
                   table, ["scenario", "SNR [dB]", "effects (× REALISTIC)", "failed fits"]
                   + [f"{m} [%]" for m in METHODS],
                   notes=["Accuracy mean ± sd over the stratified folds. SNR = 20·log10(RMS travel "
                          "of the nominal opening / noise sd). Failed fits count as misclassified "
                          "for the proposed method; the baselines see every capture."])
    write_json(out_dir, "robustness", rows)
    return rows


def run(out_dir: Path, *, seed: int = DEFAULT_SEED, quick: bool = False,
        workers: int = DEFAULT_WORKERS) -> dict:
    """The robustness table alone (the classify study also writes it)."""

    spec = clean_spec(seed, quick)
    return robustness_table(Path(out_dir), spec, None, seed=seed, quick=quick, workers=workers)
