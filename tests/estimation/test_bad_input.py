"""Every bad input gets a clear error, never a traceback or a silent number."""

import subprocess
import sys

import numpy as np
import pytest

from drivers.capture import Capture, CaptureError
from service.acquisition.capture_file import parse_csv, read_capture
from drivers.synthetic import synthesize_capture
from service.breaker_file import BreakerFileError, load_breaker
from service.estimation import FitError, fit_capture


@pytest.fixture(scope="module")
def opening(breaker):
    cap, _ = synthesize_capture(breaker, "open", breaker.design_parameters(), rng=np.random.default_rng(4))
    return cap


def _replace(cap, **kw):
    fields = dict(travel=cap.travel, sample_rate=cap.sample_rate, vibration=cap.vibration,
                  source="test", travel_limits=cap.travel_limits)
    fields.update(kw)
    return Capture(**fields)


def test_nan_travel(breaker, opening):
    travel = opening.travel.copy()
    travel[500] = np.nan
    with pytest.raises(FitError, match="NaN"):
        fit_capture(_replace(opening, travel=travel), breaker, "open")


def test_truncated_capture(breaker, opening):
    cut = int(0.05 * opening.sample_rate)  # ends mid-stroke
    cap = _replace(opening, travel=opening.travel[:cut], vibration=opening.vibration[:cut])
    with pytest.raises(FitError, match="truncated|wrong way|end position"):
        fit_capture(cap, breaker, "open")


def test_too_short(breaker, opening):
    with pytest.raises(FitError, match="too short"):
        fit_capture(_replace(opening, travel=opening.travel[:40], vibration=opening.vibration[:40]), breaker, "open")


def test_motionless(breaker, opening):
    rng = np.random.default_rng(1)
    still = rng.normal(0, 0.0015, opening.travel.size)
    with pytest.raises(FitError, match="no motion"):
        fit_capture(_replace(opening, travel=still), breaker, "open")


def test_saturated_travel(breaker, opening):
    limit = 0.9
    cap = _replace(opening, travel=np.minimum(opening.travel, limit), travel_limits=(0.0, limit))
    with pytest.raises(FitError, match="saturated"):
        fit_capture(cap, breaker, "open")


def test_degrees_mistaken_for_radians(breaker, opening):
    with pytest.raises(FitError, match="unit"):
        fit_capture(_replace(opening, travel=np.degrees(opening.travel)), breaker, "open")


def test_wrong_operation(breaker, opening):
    with pytest.raises(FitError, match="wrong way"):
        fit_capture(opening, breaker, "close")


def test_csv_with_wrong_unit_column():
    with pytest.raises(CaptureError, match="travel_rad"):
        parse_csv("t_s,travel_deg\n0,0\n0.1,1\n")


def test_csv_non_uniform_time():
    with pytest.raises(CaptureError, match="uniform"):
        parse_csv("t_s,travel_rad\n0,0\n0.1,1\n0.15,1\n")


def test_malformed_comtrade(tmp_path):
    cfg = tmp_path / "bad.cfg"
    cfg.write_text("this is not a COMTRADE file\n")
    (tmp_path / "bad.dat").write_bytes(b"\x00\x01")
    with pytest.raises(CaptureError, match="malformed COMTRADE"):
        read_capture(cfg)


def test_comtrade_without_dat(tmp_path, samples_dir):
    cfg = tmp_path / "lonely.cfg"
    cfg.write_text((samples_dir / "open-nominal.cfg").read_text())
    with pytest.raises(CaptureError, match="data file missing"):
        read_capture(cfg)


def test_comtrade_travel_in_wrong_unit(tmp_path, samples_dir):
    cfg = (samples_dir / "open-nominal.cfg").read_text().replace(",rad,", ",mm,")
    (tmp_path / "mm.cfg").write_text(cfg)
    (tmp_path / "mm.dat").write_bytes((samples_dir / "open-nominal.dat").read_bytes())
    with pytest.raises(CaptureError, match="'mm'"):
        read_capture(tmp_path / "mm.cfg")


def test_unknown_channel(samples_dir):
    with pytest.raises(CaptureError, match="no channel named 'stroke'"):
        read_capture(samples_dir / "open-nominal.cfg", travel_channel="stroke")


def test_unknown_breaker_file(tmp_path):
    with pytest.raises(BreakerFileError, match="not found"):
        load_breaker(tmp_path / "nope.toml")


def test_breaker_with_non_monotone_cam(tmp_path, breaker):
    from tests.conftest import BREAKER_FILE

    text = BREAKER_FILE.read_text().replace("reference-252kV.cam.csv", "bad-cam.csv")
    (tmp_path / "b.toml").write_text(text)
    rows = ["camshaft_rad,output_shaft_rad"] + [f"{x},{y}" for x, y in
                                                zip(np.linspace(0, 3, 10), [0, 0, .2, .4, .3, .6, .8, 1, 1, 1])]
    (tmp_path / "bad-cam.csv").write_text("\n".join(rows))
    with pytest.raises(BreakerFileError, match="not monotone"):
        load_breaker(tmp_path / "b.toml")


def _hvcb(*args):
    return subprocess.run([sys.executable, "-m", "service.cli", *args], capture_output=True, text=True,
                          timeout=120)


def test_cli_errors_are_one_line_without_traceback(tmp_path):
    (tmp_path / "x.csv").write_text("t_s,travel_rad\n0,nan\n1e-5,0\n")
    for args in (["fit", str(tmp_path / "missing.cfg"), "--operation", "open"],
                 ["fit", str(tmp_path / "x.csv"), "--operation", "open"],
                 ["fit", str(tmp_path / "x.csv"), "--operation", "open", "--breaker", str(tmp_path / "no.toml")]):
        proc = _hvcb(*args)
        assert proc.returncode == 2
        assert "Traceback" not in proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1
        assert proc.stderr.startswith("hvcb fit: error:")


@pytest.mark.parametrize("text", ["", "camshaft_rad,output_shaft_rad\n"])
def test_an_empty_cam_table_is_refused_in_words_without_a_numpy_warning(text):
    import warnings

    from service.breaker_file import BreakerFileError, cam_profile_from_text

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's "input contained no data" must not reach the console
        with pytest.raises(BreakerFileError, match="holds no data rows"):
            cam_profile_from_text(text, source="cam.csv")
