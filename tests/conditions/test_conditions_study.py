"""The quick `conditions` study on virtual-prototype captures."""

import json

import numpy as np
import pytest

from service.studies import conditions


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("conditions")
    return out, conditions.run(out, quick=True)


def test_outputs_and_keys(study):
    out, res = study
    data = json.loads((out / "conditions.json").read_text())
    assert set(data["max_deviation"]) == {"AO", "BO", "DO", "EO", "AC", "BC", "CC"}
    assert all(v is not None and v >= 0 for v in data["max_deviation"].values())
    assert (out / "conditions.md").exists()
    assert (out / "conditions_open.png").exists() and (out / "conditions_close.png").exists()
    assert list(out.glob("dataset-open-*.npz")), "the fitted dataset is cached"


def test_bo_rises_with_pre_compression(study):
    _, res = study
    means = np.array(res["series"]["open"]["means"]["BO"])
    assert np.all(np.diff(means) > 0)
    # The estimated step is of the order of kO·Δx·rO/J2 (≈150 s^-2), not noise.
    assert 0.5 * res["bo_step_theory"] < res["bo_step_estimated"] < 2.0 * res["bo_step_theory"]


def test_closing_parameters_do_not_follow_the_closing_spring(study):
    _, res = study
    for name in ("AC", "BC", "CC"):
        assert res["max_deviation"][name] < 0.05, name
