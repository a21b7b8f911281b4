"""The quick `classify` study and the CNN baseline."""

import json

import numpy as np
import pytest

from service.studies import classify
from service.studies.condition_cnn import CNN1D, torch_available


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("classify")
    return out, classify.run(out, quick=True)


def test_outputs_and_methods(study):
    out, res = study
    data = json.loads((out / "classify.json").read_text())
    expected = {"proposed", "svm", "bpnn"} | ({"cnn"} if torch_available()[0] else set())
    assert expected <= set(data["accuracy"])
    assert all(0.0 <= data["accuracy"][m] <= 1.0 for m in expected)
    for m in expected:
        assert np.sum(data["confusion"][m]) <= data["samples"]
        assert len(data["fold_accuracy"][m]) == data["folds"]
    assert (out / "classify.md").exists() and (out / "classify_confusion.png").exists()
    assert (out / "robustness.json").exists() and "SNR 30 dB" in data["robustness"]


def test_proposed_beats_chance(study):
    _, res = study
    assert res["accuracy"]["proposed"] > 1.0 / 3 + 0.2


def test_cnn_learns_a_separable_problem():
    ok, why = torch_available()
    if not ok:
        print(f"SKIP: {why}")
        pytest.skip(why)
    rng = np.random.default_rng(0)
    y = np.repeat(np.arange(3), 20)
    t = np.linspace(0, 1, 64)
    # Travel-like ramps whose onset differs by class, with noise.
    X = np.tanh((t - 0.3 - 0.2 * y[:, None]) / 0.05) + rng.normal(0, 0.2, (y.size, t.size))
    clf = CNN1D(seed=0, quick=True).fit(X, y)
    assert np.mean(clf.predict(X) == y) > 0.8
