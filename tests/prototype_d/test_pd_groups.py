"""prototype D's study set on disk: the manifest's shape, COMTRADE files the project reads back,
the clean travel beside each, determinism for a seed, and clear errors for bad arguments."""

from __future__ import annotations

import json

import numpy as np
import pytest

from drivers.capture_file import read_comtrade
from service.prototypes.d import EFFECTS, OPERATIONS, OUTSIDE, write_groups
from service.prototypes.d.groups import SAMPLES

SMALL = {"per_effect": 1, "controls": 1, "two_effect": 2, "outside": 1, "captures_per_group": 2}
OPEN_KEYS = {"AO", "BO", "CO", "DO", "EO"}
CLOSE_KEYS = {"AC", "BC", "CC", "DC"}


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    out = tmp_path_factory.mktemp("pd")
    return out, write_groups(out, seed=3, **SMALL)


def test_manifest_shape(small):
    out, manifest = small
    pairs = sum(len(OPERATIONS[n]) for n in EFFECTS)
    assert len(manifest) == pairs + 2 + 2 + len(OUTSIDE)
    assert json.loads((out / "manifest.json").read_text()) == manifest
    assert [g["group"] for g in manifest] == [f"g{i:03d}" for i in range(len(manifest))]
    singles = {(next(iter(g["effects"])), g["operation"]) for g in manifest
               if len(g["effects"]) == 1 and not g["outside_catalogue"]}
    assert singles == {(n, op) for n in EFFECTS for op in OPERATIONS[n]}
    assert sum(not g["effects"] for g in manifest) == 2
    assert {op for g in manifest if not g["effects"] for op in [g["operation"]]} == {"open", "close"}
    pairs_groups = [g for g in manifest if len(g["effects"]) == 2]
    assert len(pairs_groups) == 2
    for g in manifest:
        assert g["operation"] in ("open", "close")
        assert g["outside_catalogue"] == any(n in OUTSIDE for n in g["effects"])
        for name, s in g["effects"].items():
            assert g["operation"] in OPERATIONS[name]
            assert 0.5 <= s <= 1.5
        assert len(g["stems"]) == len(g["truths"]) == 2
        for stem, truth in zip(g["stems"], g["truths"]):
            assert stem.startswith(f"pd_{g['group']}_c")
            keys = OPEN_KEYS if g["operation"] == "open" else CLOSE_KEYS
            assert keys <= set(truth)
            assert -30 <= truth["temperature_C"] <= 40
            assert abs(truth["trigger_delay_s"] - 0.020) <= 0.5e-3
            assert 0.6 < truth["alpha0_rad"] < 0.8
            assert truth["noise"]["white_sd_rad"] > 0
            assert truth["noise"]["coloured"]["rms_rad"] > 0


def test_captures_read_back_with_their_clean_travel(small):
    out, manifest = small
    for g in manifest[:4]:
        for stem, truth in zip(g["stems"], g["truths"]):
            capture = read_comtrade(out / f"{stem}.cfg")
            clean = np.load(out / f"{stem}.clean.npy")
            assert clean.dtype == np.float64
            assert capture.sample_rate == 128_000
            assert capture.travel.size == clean.size == SAMPLES[g["operation"]]
            assert capture.vibration is not None and np.abs(capture.vibration).max() > 50
            noise = capture.travel - clean
            expected = np.hypot(truth["noise"]["white_sd_rad"],
                                truth["noise"]["coloured"]["rms_rad_record"])
            assert 0.8 * expected < noise.std() < 1.25 * expected
            # an opening rises from closed, a closing falls from open
            if g["operation"] == "open":
                assert clean[:100].mean() < 0.01 and clean[-100:].mean() > 0.9
            else:
                assert clean[:100].mean() > 0.9 and clean[-100:].mean() < 0.05


def test_deterministic_for_a_seed(tmp_path):
    sizes = {"per_effect": 0, "controls": 1, "two_effect": 0, "outside": 0, "captures_per_group": 1}
    a = write_groups(tmp_path / "a", seed=11, **sizes)
    b = write_groups(tmp_path / "b", seed=11, **sizes)
    c = write_groups(tmp_path / "c", seed=12, **sizes)
    assert a == b and a != c
    for g in a:
        for stem in g["stems"]:
            assert (tmp_path / "a" / f"{stem}.dat").read_bytes() == (tmp_path / "b" / f"{stem}.dat").read_bytes()
            np.testing.assert_array_equal(np.load(tmp_path / "a" / f"{stem}.clean.npy"),
                                          np.load(tmp_path / "b" / f"{stem}.clean.npy"))


@pytest.mark.parametrize("kwargs,words", [
    ({"seed": -1}, "seed must be at least 0"),
    ({"seed": "3"}, "seed must be a whole number"),
    ({"seed": 1, "per_effect": -2}, "per_effect must be at least 0"),
    ({"seed": 1, "captures_per_group": 0}, "captures_per_group must be at least 1"),
    ({"seed": 1, "two_effect": 1.5}, "two_effect must be a whole number"),
])
def test_bad_arguments_are_refused_in_words(tmp_path, kwargs, words):
    with pytest.raises(ValueError, match=words):
        write_groups(tmp_path, **kwargs)


def test_out_dir_that_is_a_file_is_refused(tmp_path):
    path = tmp_path / "taken"
    path.write_text("x")
    with pytest.raises(ValueError, match="exists and is not a directory"):
        write_groups(path, seed=1)
