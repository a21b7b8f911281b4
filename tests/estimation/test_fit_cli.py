import json
import subprocess
import sys

import numpy as np

from drivers.synthetic import synthesize_capture


def test_fit_json_on_csv_without_vibration(tmp_path, breaker):
    cap, truth = synthesize_capture(breaker, "open", breaker.design_parameters(),
                                    rng=np.random.default_rng(21), pre_s=0.0)
    rows = "\n".join(f"{t:.9f},{y:.7f}" for t, y in zip(cap.t, cap.travel))
    path = tmp_path / "op.csv"
    path.write_text("t_s,travel_rad\n" + rows + "\n")
    proc = subprocess.run([sys.executable, "-m", "service.cli", "fit", str(path), "--operation", "open",
                           "--json"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    for key in ("operation", "parameters", "ci95", "rmse_rad", "window_s", "evaluations", "runtime_s"):
        assert key in out
    assert out["window_s"][0] == 0.0  # no vibration: the window starts at the first sample
    for name in ("AO", "BO", "DO", "EO"):
        lo, hi = out["ci95"][name]
        assert lo < out["parameters"][name] < hi
        assert abs(out["parameters"][name] - truth.params[name]) < 4 * (hi - lo) / 2
