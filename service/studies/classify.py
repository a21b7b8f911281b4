"""Classification of opening conditions (paper Table 9): ``hvcb study classify``.

Five opening-spring settings × 40 captures = 200 samples, one 5-fold stratified split shared by
every method:

- ``proposed``: nearest nominal parameter vector (AO, BO, DO, EO estimates), nominal vectors and
  normalisation from the training folds only (:class:`NearestNominal`);
- ``svm``, ``bpnn``: scikit-learn on the raw travel window, tuned by inner CV on the training fold;
- ``cnn``: a 1-D CNN (PyTorch CPU), tuned on a validation split of the training fold.

Writes ``classify.json`` (``accuracy``: method -> mean fraction over folds; ``accuracy_sd``,
``fold_accuracy``, ``confusion``), ``classify.md``, ``classify_confusion.png``, and the
robustness table (:mod:`service.studies.robustness`) in ``robustness.json``/``.md``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from .common import DEFAULT_WORKERS
from .classification_methods import DEFAULT_SEED, METHODS, PAPER_ACCURACY, classification_spec, compare_methods
from .condition_data import build_dataset, snr_db
from .report import new_figure, save_figure, write_json, write_markdown
from .robustness import robustness_table

def run(out_dir: Path, *, seed: int = DEFAULT_SEED, quick: bool = False,
        workers: int = DEFAULT_WORKERS) -> dict:
    """Run the Table 9 comparison and the robustness table into ``out_dir``.

    Parameters
    ----------
    out_dir : Path
    seed : int
    quick : bool
        3 conditions × 6 captures, small grids, one robustness scenario (tests).
    workers : int
        Fitting processes.
    """
    out_dir = Path(out_dir)
    spec = classification_spec(seed, quick)
    data = build_dataset(spec, out_dir, workers=workers)
    cmp = compare_methods(data, seed=seed, quick=quick)
    res = cmp["methods"]
    result = {
        "accuracy": {m: res[m]["mean"] for m in res},
        "accuracy_sd": {m: res[m]["sd"] for m in res},
        "fold_accuracy": {m: res[m]["fold_accuracy"] for m in res},
        "confusion": {m: res[m]["confusion"] for m in res},
        "best_params": {m: res[m]["best_params"] for m in res},
        "runtime_s": {m: res[m]["runtime_s"] for m in res},
        "skipped": cmp["skipped"], "folds": cmp["folds"], "fit_failures": cmp["fit_failures"],
        "samples": int(data["condition"].size), "paper_accuracy": PAPER_ACCURACY,
        "dataset": dataclasses.asdict(spec), "snr_db": snr_db(spec.noise_rad, spec),
    }
    result["proposed_best"] = bool(all(result["accuracy"]["proposed"] > result["accuracy"][m]
                                       for m in ("svm", "bpnn", "cnn") if m in result["accuracy"]))
    result["robustness"] = robustness_table(out_dir, spec, data, seed=seed, quick=quick, workers=workers)
    _plot_confusion(out_dir, result)
    _write_tables(out_dir, result)
    write_json(out_dir, "classify", result)
    return result


def _plot_confusion(out_dir, result):
    names = [m for m in METHODS if m in result["confusion"]]
    fig, axes = new_figure(1, len(names), figsize=(3.0 * len(names), 3.0))
    for ax, m in zip(np.atleast_1d(axes), names):
        c = np.array(result["confusion"][m])
        ax.imshow(c, cmap="Blues")
        for (i, j), v in np.ndenumerate(c):
            ax.text(j, i, str(v), ha="center", va="center", fontsize=7)
        ax.set_title(f"{m}: {100 * result['accuracy'][m]:.1f} %")
        ax.set_xlabel("predicted condition")
        ax.set_ylabel("true condition")
        ax.set_xticks(range(len(c)), range(1, len(c) + 1))
        ax.set_yticks(range(len(c)), range(1, len(c) + 1))
    save_figure(fig, Path(out_dir) / "classify_confusion.png")


def _write_tables(out_dir, result):
    rows = []
    for m in list(METHODS) + ["proposed_global_norm"]:
        if m not in result["accuracy"]:
            rows.append([m, None, None, None, 100 * PAPER_ACCURACY.get(m, np.nan),
                         f"skipped: {result['skipped'].get(m, '')}"])
            continue
        folds = ", ".join(f"{100 * a:.1f}" for a in result["fold_accuracy"][m])
        paper = PAPER_ACCURACY.get(m)
        rows.append([m, 100 * result["accuracy"][m], 100 * result["accuracy_sd"][m], folds,
                     None if paper is None else 100 * paper, f"{result['runtime_s'][m]:.1f} s"])
    sections = [(f"confusion matrix: {m} (rows true condition, columns predicted)",
                 ["true \\ pred"] + [str(k + 1) for k in range(len(result["confusion"][m]))],
                 [[i + 1] + row for i, row in enumerate(result["confusion"][m])])
                for m in METHODS if m in result["confusion"]]
    notes = [f"{result['samples']} samples, {result['folds']}-fold stratified CV with the same folds "
             f"for every method; {result['fit_failures']} failed fits count as misclassified for "
             f"the proposed method. Travel SNR {result['snr_db']:.1f} dB.",
             "Tuned hyperparameters per fold: " + "; ".join(
                 f"{m}: {result['best_params'][m]}" for m in ("svm", "bpnn", "cnn") if m in result["best_params"])]
    write_markdown(out_dir, "classify", "Condition classification (paper Table 9)", rows,
                   ["method", "accuracy mean [%]", "sd over folds [%]", "per fold [%]", "paper [%]",
                    "runtime"], sections=sections, notes=notes)
