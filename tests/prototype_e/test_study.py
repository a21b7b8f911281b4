"""write_groups writes a consistent manifest and readable files; bad arguments are refused."""
import json
import struct

import numpy as np
import pytest

from service.prototypes.e import EFFECTS, OUTSIDE, OPERATIONS, write_groups, model as M

KEYS = {"temperature_C", "trigger_delay_s", "AO", "BO", "CO", "DO", "EO", "AC", "BC", "CC",
        "DC", "alpha0_rad", "sensor_gain", "sensor_zero_rad", "noise"}


def _read_cfg(path):
    lines = path.read_text().splitlines()
    n_ch = int(lines[1].split(",")[0])
    chans = [lines[2 + k].split(",") for k in range(n_ch)]
    i = 2 + n_ch
    i += 1  # line frequency
    nrates = int(lines[i]); i += 1
    rate, nsamp = lines[i].split(","); i += 1 + nrates - 1
    fmt = lines[i + 2].strip()
    return chans, float(rate), int(nsamp), fmt


def _read_dat(path, n_ch, nsamp):
    raw = path.read_bytes()
    rec = 8 + 2 * n_ch
    assert len(raw) == rec * nsamp
    a = np.frombuffer(raw, dtype=np.dtype([("n", "<u4"), ("t", "<u4"), ("v", "<i2", (n_ch,))]))
    return a["v"]


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    out = tmp_path_factory.mktemp("pe")
    m = write_groups(out, seed=11, per_effect=1, controls=1, two_effect=2, outside=2,
                     captures_per_group=1)
    return out, m


def test_manifest_is_consistent(small):
    out, m = small
    n_single = sum(len(OPERATIONS[e]) for e in EFFECTS)
    assert len(m) == n_single + 2 + 2 + 2 * len(OUTSIDE)
    assert json.loads((out / "manifest.json").read_text()) == json.loads(json.dumps(m))
    assert [g["group"] for g in m] == [f"g{i:03d}" for i in range(len(m))]
    seen = set()
    for g in m:
        assert g["operation"] in ("open", "close")
        for e, s in g["effects"].items():
            assert g["operation"] in OPERATIONS[e] and 0.5 <= s <= 1.5
        assert g["outside_catalogue"] == any(e in OUTSIDE for e in g["effects"])
        assert len(g["stems"]) == len(g["truths"]) == 1
        for stem, t in zip(g["stems"], g["truths"]):
            assert stem.startswith(f"pe_{g['group']}_c") and stem not in seen
            seen.add(stem)
            assert KEYS <= set(t)
            assert 0.5e-3 <= t["trigger_delay_s"] <= 3e-3 and -10 <= t["temperature_C"] <= 40
            assert t["DC"] == t["AO"]
            assert 2500 < t["AO"] < 4500 and 15000 < t["AC"] < 30000
    kinds = {(tuple(sorted(g["effects"])), g["operation"]) for g in m}
    for e in EFFECTS:
        for op in OPERATIONS[e]:
            assert ((e,), op) in kinds
    assert sum(1 for g in m if len(g["effects"]) == 2) == 2
    assert sum(1 for g in m if not g["effects"]) == 2


def test_files_are_readable(small):
    out, m = small
    for g in m:
        stem = g["stems"][0]
        chans, rate, nsamp, fmt = _read_cfg(out / f"{stem}.cfg")
        assert rate == 128000.0 and fmt == "BINARY"
        assert nsamp == (M.N_OPEN if g["operation"] == "open" else M.N_CLOSE)
        v = _read_dat(out / f"{stem}.dat", len(chans), nsamp)
        a, b = float(chans[0][5]), float(chans[0][6])
        travel = v[:, 0] * a + b
        clean = np.load(out / f"{stem}.clean.npy")
        healthy = np.load(out / f"{stem}.healthy.npy")
        assert clean.dtype == np.float64 and clean.shape == healthy.shape == (nsamp,)
        # the recording is the clean reading plus noise of a few mrad at most
        resid = (travel - clean)[clean > 0.01]
        assert np.std(resid) < 4e-3 and abs(np.mean(resid)) < 1e-3
        if g["operation"] == "open":
            assert 0.95 < clean.max() < 1.2 and abs(clean[:2000]).max() < 0.01
        else:
            assert 0.95 < clean[:2000].min() and clean.min() < 0.05
        if not g["effects"]:
            assert np.array_equal(clean, healthy)
        t = g["truths"][0]
        i0 = int(np.ceil(t["t_motion_start"] * rate))
        assert np.all(clean[: i0 - 1] == clean[0])


def test_deterministic_and_shuffled(tmp_path):
    kw = dict(seed=5, per_effect=0, controls=2, two_effect=2, outside=0, captures_per_group=1)
    m1 = write_groups(tmp_path / "a", **kw)
    m2 = write_groups(tmp_path / "b", **kw)
    assert json.dumps(m1) == json.dumps(m2)
    assert (tmp_path / "a" / "pe_g000_c0.dat").read_bytes() == (tmp_path / "b" / "pe_g000_c0.dat").read_bytes()
    m3 = write_groups(tmp_path / "c", **dict(kw, seed=6))
    assert json.dumps(m3) != json.dumps(m1)


@pytest.mark.parametrize("kw,words", [
    (dict(seed="one"), "seed must be an integer"),
    (dict(seed=1, per_effect=-1), "per_effect must be at least 0"),
    (dict(seed=1, captures_per_group=0), "captures_per_group must be at least 1"),
    (dict(seed=1, controls=2.5), "controls must be a whole number"),
    (dict(seed=1, per_effect=0, controls=0, two_effect=0, outside=0), "nothing to write"),
])
def test_bad_arguments_are_refused(tmp_path, kw, words):
    with pytest.raises(ValueError, match=words):
        write_groups(tmp_path / "x", **kw)


def test_out_dir_that_is_a_file_is_refused(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(ValueError, match="not a directory"):
        write_groups(f, seed=1)


def test_a_failed_closing_is_recognised():
    from service.prototypes.e import study
    u = M.design_unit()
    u.TCf *= 1.5  # far beyond the closing-energy margin (stalls at about +35 %)
    rng = np.random.default_rng(0)
    info = study.capture("close", u, {}, M.Conditions(20.0, 1e-3), rng)[4]
    assert info["completed"] is False
    info = study.capture("close", M.design_unit(), {}, M.Conditions(20.0, 1e-3), rng)[4]
    assert info["completed"] is True
