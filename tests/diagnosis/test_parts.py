"""Pure parts of the pipeline: the evidence's priors, the decision's size rule, the CLI's
capture expansion, the group generators' interface."""

import json
from types import SimpleNamespace

import numpy as np
import pytest

from service.diagnosis.commands import expand
from service.diagnosis.decision import MILD, gap_sigma
from service.diagnosis.errors import DiagnosisError
from service.diagnosis.evidence import evidence
from service.diagnosis.hypotheses import HypothesisFit, spline_basis


def _fits(chi, spread=None):
    """Fake fits: each hypothesis's residual spreads its χ² evenly over 500 blocks (or puts
    it all in the first 32 blocks when named in ``spread``)."""
    caps = [SimpleNamespace(J=np.zeros((500, 5)))]
    hyps = {}
    for name, (c, k) in chi.items():
        eff = () if name in ("none",) else tuple(name.split("+")) if name != "outside_catalogue" else ("x",)
        e = np.full(500, np.sqrt(c / 500))
        if spread and name in spread:
            e = np.full(500, np.sqrt(spread[name] / 500))
            e[:32] = np.sqrt((e[:32] ** 2) + (c - spread[name]) / 32)
        hyps[name] = HypothesisFit(eff, {}, k, c, [c], outside=name == "outside_catalogue", resid=[e])
    return SimpleNamespace(windows=SimpleNamespace(n=500, captures=caps), hypotheses=hyps)


def test_evidence_priors_and_bic():
    f = _fits({"none": (520.0, 0), "a": (480.0, 2), "b": (500.0, 2), "a+b": (478.0, 4),
               "outside_catalogue": (470.0, 10)})
    ev = evidence(f)
    assert sum(ev.probabilities.values()) == pytest.approx(1.0)
    assert ev.prior["a+b"] == pytest.approx(ev.prior["a"] / 2)     # pair: 1/F of a single (F = 2)
    assert ev.prior["none"] == ev.prior["a"] == ev.prior["outside_catalogue"]
    # evidence spread evenly over the units: the bootstrap leaves the BIC odds nearly unchanged
    # (the last unit is shorter, which adds a little spread): a beats none by Δχ² 40 − 2 ln 500
    # = 27.6 → ln odds 13.8
    odds = ev.probabilities["a"] / ev.probabilities["none"]
    assert np.log(odds) == pytest.approx(0.5 * (40 - 2 * np.log(500)), rel=0.02)


def test_evidence_from_one_unit_is_tempered():
    chi = {"none": (520.0, 0), "a": (480.0, 2), "outside_catalogue": (470.0, 10)}
    even = evidence(_fits(chi))
    local = evidence(_fits(chi, spread={"none": 480.0}))     # none's excess all in one 4 ms unit
    assert local.probabilities["a"] < even.probabilities["a"]
    assert local.probabilities["a"] > 0.5


def test_dispersion_tempers_a_misspecified_fit():
    f = _fits({"none": (2000.0, 0), "a": (1500.0, 2), "outside_catalogue": (1000.0, 10)})
    ev = evidence(f)
    assert ev.dispersion == pytest.approx(1000.0 / (500 - 5 - 10))


def test_size_rule():
    assert gap_sigma(500.0, 500) == 0.0
    # a misfit of exactly one block-mean sd per sample: χ²/n = 1 + 16·(1/16)
    assert gap_sigma(1000.0, 500) == pytest.approx(MILD)


def test_spline_basis_partition_of_unity():
    B = spline_basis(np.linspace(0.0, 0.05, 300))
    assert B.shape == (300, 8)
    assert np.allclose(B.sum(axis=1), 1.0)


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
