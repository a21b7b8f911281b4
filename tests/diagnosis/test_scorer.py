"""The learnt scorer, the answer's set and the naming rule (issue 48), on hand-made features:
each check can fail. The shipped scorer itself: tests/diagnosis/test_shipped_scorer.py."""

import json

import numpy as np
import pytest

from service.diagnosis import scorer as S
from service.diagnosis.answer_set import answer_set
from service.studies.gap import train


def _feats(elpds: dict, shrinks: dict | None = None, chi2=1400.0, dof=1000.0, units=5):
    """A group's features: hypotheses {name: elpd}, their per-unit shrink (default 0)."""
    hyp = {"none": {"elpd": 0.0, "lpd": [0.0] * units, "dim": 0, "shrink": [0.0] * units, "shrink_all": 0.0,
                    "where": 0.5, "where_sd": 0.0}}
    for k, v in elpds.items():
        sh = (shrinks or {}).get(k, 0.0)
        hyp[k] = {"elpd": float(v), "lpd": [v / units] * units, "dim": 3 if "+" not in k else 6,
                  "shrink": [sh] * units, "shrink_all": sh, "where": 0.6, "where_sd": 0.1}
    hyp["outside_catalogue"] = {"elpd": 0.5 * max(elpds.values(), default=0.0), "lpd": [0.0] * units, "dim": 8}
    return {"group": {"rows": dof + 20, "dof": dof, "units": units, "captures": units, "chi2": chi2,
                      "gap_sigma": (chi2 - dof) / np.sqrt(2 * dof), "whiteness": 1.0, "where": 0.6,
                      "where_sd": 0.2}, "hypotheses": hyp}


def test_features_are_relative_to_none_and_to_the_best_in_units_of_the_gap():
    f = _feats({"orifice_buffer": 150.0, "puffer_gas": 50.0})
    G = S.gap_scale(f["group"])
    assert G == pytest.approx(200.0)                       # ½(χ² − dof)
    names, X = S.design(f)
    assert names[0] == "none" and set(names) == {"none", "orifice_buffer", "puffer_gas", "outside_catalogue"}
    col = {k: i for i, k in enumerate(S.FEATURES)}
    ob, pg, no = X[names.index("orifice_buffer")], X[names.index("puffer_gas")], X[0]
    assert ob[col["elpd_over_gap"]] == pytest.approx(0.75) and ob[col["is_best"]] == 1.0
    assert pg[col["elpd_minus_best_over_gap"]] == pytest.approx(-0.5) and pg[col["is_best"]] == 0.0
    assert no[col["is_none"]] == 1.0 and no[col["elpd_over_gap"]] == 0.0 and no[col["has_orifice_buffer"]] == 0.0
    assert ob[col["has_orifice_buffer"]] == 1.0 and ob[col["has_puffer_gas"]] == 0.0
    # a gap within the noise: the scale is the noise's own sd, not a ratio of two noises
    assert S.gap_scale(_feats({"a": 1.0}, chi2=990.0)["group"]) == pytest.approx(0.5 * np.sqrt(2000.0))


def test_a_scorer_with_other_features_is_refused_naming_the_file(tmp_path):
    d = S.Scorer(np.zeros(len(S.FEATURES)), np.zeros(len(S.FEATURES)), np.ones(len(S.FEATURES))).to_dict()
    d["features"] = d["features"][:-1]
    with pytest.raises(S.ScorerError, match="scorer.json: its features"):
        S.Scorer.from_dict(d, str(tmp_path / "scorer.json"))


def _synthetic(rng, n):
    """Groups whose truth is the hypothesis that shrinks the gap on every capture (its elpd is
    no larger than a decoy's: the elpd alone cannot tell them apart)."""
    effects = ["orifice_buffer", "puffer_gas", "stribeck_friction", "viscous_friction"]
    items = []
    for _ in range(n):
        truth = effects[int(rng.integers(len(effects)))]
        decoy = effects[(effects.index(truth) + 1) % len(effects)]
        el = {e: float(rng.uniform(0, 30)) for e in effects}
        el[truth] = el[decoy] = float(rng.uniform(80, 120))
        sh = {e: float(rng.uniform(-0.2, 0.3)) for e in effects}
        sh[truth] = float(rng.uniform(0.7, 1.0))
        f = _feats(el, sh)
        names, X = S.design(f)
        items.append({"row": {"prototype": "x", "variant": "clean", "n": 5}, "names": names, "X": X,
                      "y": names.index(truth)})
    return items


def test_the_conditional_logit_learns_what_the_elpd_alone_cannot_tell():
    rng = np.random.default_rng(48)
    sc = train.fit(_synthetic(rng, 200))
    test = _synthetic(rng, 200)
    top = [int(np.argmax(train.probabilities(sc, it))) == it["y"] for it in test]
    assert np.mean(top) >= 0.9
    # saved as data and loaded without the trainer: the same probabilities
    back = S.Scorer.from_dict(json.loads(json.dumps(sc.to_dict())))
    p0 = train.probabilities(sc, test[0])
    p1 = S.softmax_rows(back.utilities(test[0]["X"]))
    assert np.allclose(p0, p1)


def test_aps_sets_cover_at_the_level_on_exchangeable_groups():
    rng = np.random.default_rng(7)
    K = 6

    def draw(n):
        out = []
        for _ in range(n):
            logits = rng.normal(size=K) * 1.5
            p = np.exp(logits) / np.exp(logits).sum()
            out.append((p, int(rng.choice(K, p=p))))       # the probabilities are the truth's law
        return out

    cal, test = draw(1000), draw(3000)
    q = train.aps_quantile([train.aps_score(p, y) for p, y in cal], 0.1)
    names = [str(k) for k in range(K)]
    hits = [str(y) in train.aps_set(names, p, q) for p, y in test]
    assert 0.88 <= np.mean(hits) <= 0.93
    # with too few calibration groups nothing can be certified: the whole catalogue
    assert train.aps_quantile([0.5] * 5, 0.1) == 1.0


def test_learn_then_test_names_only_when_wrong_names_are_rare():
    rng = np.random.default_rng(1)
    good = [(np.array([0.99, 0.01]), 0) for _ in range(400)]
    lam, tested = train.name_threshold([p for p, _ in good], [y for _, y in good])
    assert lam is not None and lam <= 0.99
    bad = [(np.array([0.99, 0.01]), int(rng.random() < 0.2)) for _ in range(400)]   # 20 % wrong at 0.99
    lam, tested = train.name_threshold([p for p, _ in bad], [y for _, y in bad])
    assert lam is None or lam > 0.99
    assert all(t["p"] >= 0 for t in tested)


def test_the_answer_set_states_a_name_only_past_the_threshold():
    probs = {"none": 0.02, "orifice_buffer": 0.93, "puffer_gas": 0.05}
    a = answer_set(probs, qhat=0.95, lam=0.9)
    assert a.status == "named" and a.members == ["orifice_buffer"]
    a = answer_set(probs, qhat=0.95, lam=None)              # no threshold certified: never named
    assert a.status == "ambiguous" and a.members == ["orifice_buffer", "puffer_gas"]   # none: 0.98 above it
    a = answer_set(probs, qhat=0.5, lam=None)
    assert a.members == ["orifice_buffer"] and a.status == "ambiguous"
    a = answer_set({"none": 0.97, "outside_catalogue": 0.03}, qhat=0.9, lam=0.95)
    assert a.status == "none" and a.labels == ["none"]
    a = answer_set({"none": 0.3, "outside_catalogue": 0.6, "x": 0.1}, qhat=0.85, lam=0.95)
    assert a.status == "ambiguous" and a.labels == ["unexplained", "none"]     # x: 0.9 above it > 0.85
