"""Quick versions of the paper's studies: files, keys, and physics that could go wrong."""

import json

import numpy as np
import pytest

from service.cli import main
from service.studies import identifiability, optimizers
from service.studies.commands import run_study


def _outputs(out, name):
    data = json.loads((out / f"{name}.json").read_text())
    assert (out / f"{name}.md").read_text().startswith("# ")
    assert list(out.glob(f"{name}*.png"))
    return data


def test_sensitivity_cli_writes_table_5(tmp_path):
    assert main(["study", "sensitivity", "--out", str(tmp_path)]) == 0
    data = _outputs(tmp_path, "sensitivity")
    coeff = data["coefficients"]
    assert set(coeff) == {"AO", "BO", "DO", "EO", "AC", "BC", "CC"}
    for name, s in coeff.items():
        assert s["plus"] > 0 and s["minus"] > 0, name
        # ±5 % steps of a smooth model: the two one-sided coefficients agree to within 25 %
        assert s["plus"] == pytest.approx(s["minus"], rel=0.25), name
    # The buffer acts only past α0, so DO and EO move the curve far less than the springs do.
    assert coeff["DO"]["mean"] < 0.2 * coeff["BO"]["mean"]
    assert coeff["EO"]["mean"] < 0.2 * coeff["BO"]["mean"]


def test_identifiability_quick(tmp_path):
    summary = run_study("identifiability", tmp_path, quick=True, workers=2)
    data = _outputs(tmp_path, "identifiability")
    assert set(data["results"]) == {"P0", "P1"}
    assert len(data["fits"]) == 2 * data["n_sets"]
    p0 = data["results"]["P0"]["metrics"]
    # Noise-free opening: the closed-form model is exact, so AO comes back to < half of Table 3.
    assert p0["AO"]["MRE_pct"] <= 0.5 * identifiability.PAPER_P0_MRE["AO"]
    assert p0["BO"]["MRE_pct"] <= 0.5 * identifiability.PAPER_P0_MRE["BO"]
    assert p0["AO"]["R2"] > 0.999
    p1 = data["results"]["P1"]
    # The coverage is the share of P1 fits whose interval holds the truth, recounted here.
    p1_fits = [r for r in data["fits"] if r["protocol"] == "P1" and "AO" in r["ci95"]]
    inside = [r["ci95"]["AO"][0] <= r["truth"]["AO"] <= r["ci95"]["AO"][1] for r in p1_fits]
    assert p1_fits and p1["coverage"]["AO"] == pytest.approx(np.mean(inside))
    # Noise costs accuracy: P1 errors exceed P0's for the opening spring.
    assert p1["metrics"]["AO"]["MRE_pct"] > p0["AO"]["MRE_pct"]
    # The verdict follows from the figures: each parameter's coverage against the 90–99 % band.
    acc = summary["acceptance"]
    lo, hi = identifiability.COVERAGE_BAND
    for name, ok in acc["per_parameter"]["P1_coverage"].items():
        assert ok == (lo <= p1["coverage"][name] <= hi), name
    assert acc["P1_coverage_90_to_99pct"] == all(acc["per_parameter"]["P1_coverage"].values())


def test_correlation_quick_crlb_is_finite_positive(tmp_path):
    run_study("correlation", tmp_path, quick=True, workers=2)
    data = _outputs(tmp_path, "correlation")
    eff = data["efficiency"]
    assert set(eff) == {"AO", "BO", "DO", "EO", "AC", "BC", "CC"}
    for name, e in eff.items():
        assert e["crlb_sd"] > 0 and np.isfinite(e["crlb_sd"]), name
        assert e["efficiency"] is not None and e["efficiency"] > 0, name
    P = np.array(data["results"]["open"]["pearson"])
    assert P.shape == (4, 4)
    assert np.allclose(np.diag(P), 1.0) and np.allclose(P, P.T)
    # The bound is far below the parameter values at 50 dB (a few tenths of a percent for AO).
    assert eff["AO"]["crlb_sd"] < 0.01 * data["truth"]["AO"]


def test_optimizers_quick(tmp_path):
    if not optimizers.nevergrad_available():
        pytest.skip("nevergrad is not importable: PSO and GA cannot run")
    run_study("optimizers", tmp_path, quick=True)
    data = _outputs(tmp_path, "optimizers")
    res = data["results"]
    assert set(res) == {"CMA-ES", "PSO", "GA", "DE", "NLS"}
    assert np.isfinite(res["CMA-ES"]["MRE_pct"]) and res["CMA-ES"]["MRE_pct"] < 50
    for name, r in res.items():
        assert r["evaluations"] > 0 and r["iterations"] <= optimizers.MAX_ITERATIONS, name
        # Every method ends at least as good as a model 10× the noise level off the data.
        assert r["fitness_rmse_mean_rad"] < 10 * data["noise_rad"], name
