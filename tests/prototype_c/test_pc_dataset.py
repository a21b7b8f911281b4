"""Prototype C interface: write_groups (determinism, manifest, COMTRADE), and bad arguments."""

import json

import numpy as np
import pytest

from service.prototypes.c import EFFECTS, OPERATIONS, make_unit, simulate_capture, write_groups
from service.prototypes.c.dataset import _plan


def test_plan_has_every_group_kind():
    plan = _plan(np.random.default_rng(0), 4, 6, 4, 2)
    pairs = sum(len(OPERATIONS[n]) for n in EFFECTS)
    assert len(plan) == 4 * pairs + 2 * 6 + 4 + 2 * 2
    assert sorted(op for op, e in plan if "sensor_lag" in e) == ["close", "open"]
    two = [(op, e) for op, e in plan if len(e) == 2]
    assert len(two) == 4 and all(all(op in OPERATIONS[n] for n in e) for op, e in two)


def _small(tmp, seed):
    return write_groups(tmp, seed=seed, per_effect=0, controls=1, two_effect=1, outside=0, captures_per_group=2)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The same small data set written twice with one seed."""
    root = tmp_path_factory.mktemp("pc")
    return _small(root / "a", 11), root / "a", root / "b", _small(root / "b", 11)


def test_write_groups_is_deterministic_and_its_manifest_is_complete(written):
    man, a, b, _ = written
    assert json.loads((a / "manifest.json").read_text()) == json.loads((b / "manifest.json").read_text())
    assert len(man) == 3
    for g in man:
        assert set(g) == {"group", "operation", "effects", "outside_catalogue", "stems", "truths"}
        assert len(g["stems"]) == len(g["truths"]) == 2
        for stem, truth in zip(g["stems"], g["truths"]):
            assert stem.startswith("pc_g") and not any(n in stem for n in EFFECTS)
            assert (a / f"{stem}.dat").read_bytes() == (b / f"{stem}.dat").read_bytes()
            assert "BINARY" in (a / f"{stem}.cfg").read_text()
            assert truth["operation"] == g["operation"] and truth["effects"] == g["effects"]
            assert set(truth["params"]) == ({"AO", "BO", "CO", "DO", "EO"} if g["operation"] == "open"
                                            else {"AC", "BC", "CC"})
            for key in ("t_shock_s", "t_motion_s", "t_end_of_stroke_s", "conditions", "constants", "shapes"):
                assert key in truth
        # conditions are drawn per capture, the unit is one per group
        assert g["truths"][0]["conditions"] != g["truths"][1]["conditions"]
        assert g["truths"][0]["constants"] == g["truths"][1]["constants"]
    assert sum(len(g["effects"]) == 2 for g in man) == 1
    assert not list(a.glob("*.tmp")) and not list(a.glob(".*"))
    hdr = (a / f"{man[-1]['stems'][0]}.hdr").read_text()
    assert not any(n in hdr for n in EFFECTS)          # the effect is only in the manifest


@pytest.mark.parametrize("group", [0, 1])
def test_written_capture_reads_back(written, group):
    comtrade = pytest.importorskip("comtrade")
    man, a, _, _ = written
    stem, truth = man[group]["stems"][0], man[group]["truths"][0]
    rec = comtrade.Comtrade()
    rec.load(str(a / f"{stem}.cfg"), str(a / f"{stem}.dat"))
    assert rec.cfg.sample_rates[0][0] == 128000
    travel = np.asarray(rec.analog[0])
    i = int(truth["t_end_of_stroke_s"] * 128000)
    assert travel[:2000].std() < 3e-3 and abs(travel[:2000].mean() - (0 if truth["operation"] == "open" else 1)) < 2e-3
    if truth["operation"] == "open":     # the stroke's end: about 1 rad open, or closed
        assert 0.9 < travel[i] < 1.15
    else:
        assert abs(travel[i]) < 5e-3


def test_noise_is_the_requested_gaussian():
    unit = make_unit(np.random.default_rng(0))
    cap, _ = simulate_capture(unit, "open", rng=np.random.default_rng(1))
    rest = cap.travel[:2400]
    assert rest.std() == pytest.approx(1.5e-3, rel=0.1)
    vib = cap.vibration
    assert np.abs(vib[2480:2560]).max() > 50 and np.abs(vib[:2000]).max() < 5   # shock 0.4 ms before motion


@pytest.mark.parametrize("effects,msg", [({"rust": 1.0}, "unknown effect 'rust'"),
                                         ({"viscous_friction": -1}, "must be in"),
                                         ({"viscous_friction": "x"}, "must be a number"),
                                         (["viscous_friction"], "must be a dict")])
def test_make_unit_rejects_bad_effects(effects, msg):
    with pytest.raises(ValueError, match=msg):
        make_unit(np.random.default_rng(0), effects=effects)


def test_effect_on_the_wrong_operation_is_refused():
    unit = make_unit(np.random.default_rng(0), effects={"contact_wipe": 1.0})
    with pytest.raises(ValueError, match="contact_wipe act only in close, not in a open operation"):
        simulate_capture(unit, "open", rng=np.random.default_rng(0))
    unit = make_unit(np.random.default_rng(0), effects={"orifice_buffer": 1.0})
    with pytest.raises(ValueError, match="orifice_buffer"):
        simulate_capture(unit, "close", rng=np.random.default_rng(0))


@pytest.mark.parametrize("kwargs,msg", [({"operation": "trip"}, "operation must be"),
                                        ({"conditions": {"humidity": 1}}, "unknown condition 'humidity'"),
                                        ({"conditions": {"friction": 5.0}}, "outside the physical range"),
                                        ({"noise_rad": -1.0}, "noise_rad"),
                                        ({"rng": 3}, "numpy Generator")])
def test_simulate_capture_rejects_bad_arguments(kwargs, msg):
    unit = make_unit(np.random.default_rng(0))
    args = {"operation": "open", "rng": np.random.default_rng(0), **kwargs}
    op = args.pop("operation")
    with pytest.raises(ValueError, match=msg):
        simulate_capture(unit, op, **args)


def test_write_groups_rejects_bad_counts(tmp_path):
    with pytest.raises(ValueError, match="per_effect must be a non-negative integer"):
        write_groups(tmp_path, seed=1, per_effect=-1)
    with pytest.raises(ValueError, match="captures_per_group must be at least 1"):
        write_groups(tmp_path, seed=1, captures_per_group=0)
