"""Pure parts of the pipeline: the evidence (nested likelihood ratio, noise model), the
discrepancy term, blocks in time, the CLI's capture expansion, the group
generators' interface (the study's scoring: tests/studies/test_gap_scoring.py)."""

import json
from types import SimpleNamespace

import numpy as np
import pytest

from service.diagnosis.commands import expand
from service.diagnosis.data import block_samples
from service.diagnosis.decision import gap_sigma
from service.diagnosis.discrepancy import KNOT_S, Discrepancy, basis
from service.diagnosis.errors import DiagnosisError
from service.diagnosis.evidence import evidence, lag1
from service.diagnosis.hypotheses import HypothesisFit


def _disc(v, k=40, seed=0):
    """A discrepancy term on residual ``v`` (one capture, whitened) with a k-column spline basis."""
    t = np.linspace(0.0, 0.05, v.size)
    B = basis(t, np.linspace(0.0, 0.05, k - 2)[1:-1])
    return Discrepancy([B], [B.T @ B], [B.T @ v], [v], [None], [1.5e-3])


def _fits(chi, v):
    """Fake fits: hypotheses {name: (χ², k)} over 500 blocks; ``outside`` = the best catalogued
    plus a discrepancy term on residual ``v``."""
    caps = [SimpleNamespace(Q=np.zeros((500, 5)))]
    hyps = {}
    for name, (c, k) in chi.items():
        eff = () if name == "none" else tuple(name.split("+"))
        hyps[name] = HypothesisFit(eff, {}, k, c, [c])
    best = min(hyps.values(), key=lambda h: h.chi2 + h.k * np.log(500))
    d = _disc(v)
    res = d.ls_residuals()
    hyps["outside_catalogue"] = HypothesisFit(best.effects, {}, best.k + d.k, float(np.sum(res[0] ** 2)), [],
                                              outside=True, discrepancy=d, base_k=best.k)
    return SimpleNamespace(windows=SimpleNamespace(n=500, captures=caps), hypotheses=hyps)


def test_evidence_is_the_nested_likelihood_ratio():
    v = np.random.default_rng(1).normal(size=500)
    f = _fits({"none": (540.0, 0), "a": (500.0, 2), "b": (520.0, 2), "a+b": (499.0, 4)}, v)
    ev = evidence(f)
    assert sum(ev.probabilities.values()) == pytest.approx(1.0)
    assert ev.prior["a+b"] == pytest.approx(ev.prior["a"] / 2)     # pair: 1/F of a single (F = 2)
    assert ev.prior["none"] == ev.prior["a"] == ev.prior["outside_catalogue"]
    # ln odds a : none = ½(Δχ²/s² − k ln n_eff), s² the in-motion scale estimated from the residual
    odds = np.log(ev.probabilities["a"] / ev.probabilities["none"])
    assert odds == pytest.approx(0.5 * (40.0 / ev.s2 - 2 * np.log(ev.n_eff)), rel=1e-9)
    assert 0.8 < ev.dispersion < 1.2 and ev.rho < 0.2     # white unit noise: φ ≈ 1, no AR inflation
    # a noise residual: the discrepancy loses. Its cheapest form, one 8-column stretch, costs
    # ≥ 0.1 nat a column (g ≥ 1: ½ln2 − ¼) and half the prior: odds ≤ ½e^-0.8 ≈ 0.22 by the
    # penalty alone, and this residual's fluctuations make it e^-4 on one capture
    assert ev.probabilities["outside_catalogue"] < 0.22 * ev.probabilities["a"]
    assert ev.log_bf_discrepancy < -1.5


def test_ar1_noise_inflates_the_scale():
    rng = np.random.default_rng(2)
    e = rng.normal(size=600)
    ar = np.empty_like(e)
    ar[0] = e[0]
    for i in range(1, e.size):
        ar[i] = 0.6 * ar[i - 1] + np.sqrt(1 - 0.36) * e[i]
    assert lag1([ar]) == pytest.approx(0.6, abs=0.1)
    assert abs(lag1([e])) < 0.1


def test_discrepancy_sees_a_1ms_transient():
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 0.05, 400)                  # 8 kHz blocks over 50 ms
    noise = rng.normal(size=t.size)
    bump = 3.0 * np.exp(-0.5 * ((t - 0.02) / 0.5e-3) ** 2)     # a ~1 ms transient, 3 block sd high
    k = int(0.05 / KNOT_S)
    assert _disc(noise, k).log_bf(1.0) < -2.0        # noise only: no discrepancy (odds < 1:7 on one capture)
    d = _disc(noise + bump, k)
    assert d.log_bf(1.0) > 10.0
    fit = d.posterior_fit(1.0)[0]
    assert abs(t[int(np.argmax(np.abs(fit)))] - 0.02) < 1e-3     # and it says where


def test_gap_sigma_in_time_blocks():
    assert gap_sigma(500.0, 500, 16.0) == 0.0
    # a misfit of exactly one block-mean sd per sample: χ²/n = 1 + 16·(1/16)
    assert gap_sigma(1000.0, 500, 16.0) == pytest.approx(0.25)
    assert gap_sigma(1000.0, 500, 1.0) == pytest.approx(1.0)      # a 5 kS/s record: one sample a block
    assert block_samples(128_000) == 16 and block_samples(5_000) == 1 and block_samples(64_000) == 8


def test_expand_dir_glob_and_errors(tmp_path):
    for n in ("b.cfg", "a.cfg", "a.dat", "notes.txt"):
        (tmp_path / n).write_text("x")
    assert expand([str(tmp_path)]) == [str(tmp_path / "a.cfg"), str(tmp_path / "b.cfg")]
    assert expand([str(tmp_path / "*.cfg")]) == [str(tmp_path / "a.cfg"), str(tmp_path / "b.cfg")]
    with pytest.raises(DiagnosisError, match="matches no capture"):
        expand([str(tmp_path / "*.cff")])
    with pytest.raises(DiagnosisError, match="no such file"):
        expand([str(tmp_path / "missing.cfg")])
    (tmp_path / "empty").mkdir()
    with pytest.raises(DiagnosisError, match="holds no capture"):
        expand([str(tmp_path / "empty")])


@pytest.mark.parametrize("proto", ["a", "b"])
def test_group_generators_interface(proto, tmp_path):
    import importlib
    g = importlib.import_module(f"service.prototypes.{proto}.groups")
    rng = np.random.default_rng(7)
    c = g.draw_conditions(rng)
    assert set(c) == {"friction", "buffer_damping", "puffer", "spring_charge", "temperature_c"}
    assert 0.85 <= c["friction"] <= 1.15 and 0.85 <= c["buffer_damping"] <= 1.20
    assert 0.9 <= c["puffer"] <= 1.1 and 0.99 <= c["spring_charge"] <= 1.01
    m = g.write_groups(tmp_path, seed=3, per_effect=0, controls=1, two_effect=0, outside=1, captures_per_group=2)
    assert [gr["outside_catalogue"] for gr in m["groups"]] == [False, True]
    for gr in m["groups"]:
        assert set(gr) >= {"group", "operation", "effects", "outside_catalogue", "stems", "truths"}
        assert len(gr["stems"]) == 2 and all((tmp_path / f"{s}.cfg").exists() for s in gr["stems"])
        conds = [t["conditions"] for t in gr["truths"]]
        assert conds[0] != conds[1]                       # conditions vary per capture
    assert json.loads((tmp_path / "manifest.json").read_text())["groups"][0]["effects"] == {}


def test_measurement_separation():
    from service.diagnosis.measurement import _separation

    cw = SimpleNamespace(project_out=lambda v: v)
    a = np.array([1.0, 2.0, 0.0])
    assert _separation([cw], [a], [3 * a]) == pytest.approx(0.0)          # b rescaled mimics a exactly
    b = np.array([0.0, 0.0, 2.0])
    assert _separation([cw], [a], [b]) == pytest.approx(min(5.0, 4.0))    # orthogonal: the smaller one is left
