"""Valid-interval curves: a capture that holds exactly the paper's valid interval (from rest to
the maximum of θ) is complete; one cut while the mechanism still moves is truncated.

Curves are Eq. 11 (opening) and Eq. 7 (closing) from the project's model, with parameters in
Table 2's ranges and 50 dB noise, run through the `hvcb fit` command."""

import contextlib
import io
import json
import subprocess
import sys

import numpy as np
import pytest

from drivers.capture import Capture
from service.acquisition.comtrade_writer import write_comtrade
from drivers.synthetic import operation_travel
from service.cli import main as hvcb
from service.mechanics.coordinates import operation_coordinate
from service.studies.synthetic_sets import draw_parameter_sets, operation_params
from service.studies.valid_interval import valid_interval_curve, write_csv

FS = 128_000.0


@pytest.fixture(scope="module")
def parameter_sets(breaker):
    sets, _ = draw_parameter_sets(breaker, 2, np.random.default_rng(1010))
    return sets


def hvcb_fit(path, operation, *extra):
    """`hvcb fit PATH --operation OP --json` in a fresh process."""
    return subprocess.run([sys.executable, "-m", "service.cli", "fit", str(path), "--operation", operation,
                           "--json", *extra], capture_output=True, text=True, timeout=300)


def hvcb_fit_here(path, operation, *extra):
    """The same command in this process (the command's own path, without the process start)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = hvcb(["fit", str(path), "--operation", operation, "--json", *extra])
    return subprocess.CompletedProcess([], rc, out.getvalue(), err.getvalue())


def assert_fit_recovers(out, truth, names):
    for name in names:
        lo, hi = out["ci95"][name]
        half = (hi - lo) / 2
        assert abs(out["parameters"][name] - truth[name]) < 4 * half, (name, out["parameters"][name], truth[name])


def test_opening_and_closing_that_end_at_their_maximum_are_fitted(tmp_path, breaker, parameter_sets):
    p = parameter_sets[0]
    rng = np.random.default_rng(20)
    t, travel, t_peak = valid_interval_curve(breaker, "open", p, rng=rng)
    proc = hvcb_fit(write_csv(tmp_path / "open.csv", t, travel), "open")
    assert proc.returncode == 0, proc.stderr
    opening = json.loads(proc.stdout)
    assert abs(opening["window_s"][1] - t_peak) < 1e-3  # the window runs to the maximum
    assert_fit_recovers(opening, p, ("AO", "BO", "DO", "EO"))

    t, travel, t_peak = valid_interval_curve(breaker, "close", p, rng=rng)
    proc = hvcb_fit(write_csv(tmp_path / "close.csv", t, travel), "close",
                    "--dc", repr(opening["parameters"]["AO"]))
    assert proc.returncode == 0, proc.stderr
    closing = json.loads(proc.stdout)
    assert abs(closing["window_s"][1] - t_peak) < 1e-3
    assert_fit_recovers(closing, p, ("AC", "BC", "CC"))


def test_comtrade_that_ends_at_the_maximum_is_fitted(tmp_path, breaker, parameter_sets):
    p = parameter_sets[0]
    t, travel, t_peak = valid_interval_curve(breaker, "open", p, rng=np.random.default_rng(33))
    cfg = write_comtrade(Capture(travel=travel, sample_rate=FS, travel_limits=(0.0, np.pi),
                                 source="valid-interval"), tmp_path, "open-valid", format="FLOAT32")
    proc = hvcb_fit_here(cfg, "open")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert abs(out["window_s"][1] - t_peak) < 1e-3
    assert_fit_recovers(out, p, ("AO", "BO", "DO", "EO"))


def cut_while_moving(breaker, operation, params, fraction):
    """Time before the maximum [s] at which the noise-free speed has fallen to ``fraction`` of
    its peak: the curve is still clearly moving there."""
    t = np.arange(0.0, 0.2, 1 / FS)
    full, t_peak, _ = operation_travel(breaker, operation, operation_params(params, operation), t)
    n = int(t_peak * FS)
    y = operation_coordinate(full[:n], operation, breaker.stroke)
    v = np.gradient(y, t[:n])
    i_peak_speed = int(np.argmax(v))
    i_cut = i_peak_speed + int(np.argmax(v[i_peak_speed:] < fraction * v[i_peak_speed]))
    return t_peak - t[i_cut]


@pytest.mark.parametrize("operation", ["open", "close"])
def test_curve_cut_while_still_moving_is_truncated(tmp_path, breaker, parameter_sets, operation):
    p = parameter_sets[1]
    before = cut_while_moving(breaker, operation, p, 0.25)
    assert before > 0.5e-3
    t, travel, _ = valid_interval_curve(breaker, operation, p, rng=np.random.default_rng(44),
                                        cut_before_s=before)
    proc = hvcb_fit_here(write_csv(tmp_path / "cut.csv", t, travel), operation)
    assert proc.returncode == 2
    assert "truncated" in proc.stderr
    assert "cut.csv" in proc.stderr  # the message names the file
    assert "Error" not in proc.stderr and "Traceback" not in proc.stderr


def test_noise_free_curve_that_ends_at_its_maximum_is_complete(breaker, parameter_sets):
    from service.estimation.window import prepare_window

    for operation in ("open", "close"):
        t, travel, t_peak = valid_interval_curve(breaker, operation, parameter_sets[0],
                                                 rng=np.random.default_rng(0), snr_db=None)
        window = prepare_window(Capture(travel=travel, sample_rate=FS, source="clean"), breaker, operation)
        assert abs(window.t_end - t_peak) < 1e-3, operation


def test_fits_on_valid_interval_csvs_meet_table4(tmp_path, breaker):
    """`hvcb fit` on a few valid-interval CSVs (opening, then closing with --dc = the opening's
    AO): the mean relative error of every parameter is within the paper's Table 4 (50 dB).
    bench/valid_interval.py runs the same on 40 sets."""
    from service.studies.identifiability import PAPER_P1_MRE
    from service.studies.synthetic_sets import error_metrics

    sets, _ = draw_parameter_sets(breaker, 6, np.random.default_rng(606))
    estimates = {k: [] for k in PAPER_P1_MRE}
    for i, p in enumerate(sets):
        dc = []
        for operation in ("open", "close"):
            t, travel, _ = valid_interval_curve(breaker, operation, p, rng=np.random.default_rng([606, i]))
            csv = write_csv(tmp_path / f"{operation}-{i}.csv", t, travel)
            proc = hvcb_fit_here(csv, operation, *dc)
            assert proc.returncode == 0, proc.stderr
            fitted = json.loads(proc.stdout)["parameters"]
            for name, value in fitted.items():
                estimates[name].append(value)
            dc = ["--dc", repr(fitted["AO"])] if operation == "open" else dc
    for name, limit in PAPER_P1_MRE.items():
        mre = error_metrics([p[name] for p in sets], estimates[name])["MRE_pct"]
        assert mre < limit, (name, mre, limit)
