"""A breaker history on a real database: real capture files, fit results landed by the storage
layer, and the real drift detector raising real alarms (with their evidence and baselines).
The fits themselves are not run (the parameters are given), which keeps the test fast."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

from service.storage import crud
from service.storage.spool import write_capture_file

BREAKER_FILE = Path(__file__).resolve().parents[2] / "config" / "breakers" / "reference-252kV.toml"
# baseline_max = baseline_n: a frozen 12-fit baseline, so the retention tests know which captures
# a baseline protects (a learning window would protect every quiet fit up to baseline_max).
ALARMS = {"baseline_n": 12, "baseline_max": 12, "watched": {"DO": "falling"}}


def synth_captures():
    """One opening capture of the reference breaker (with its vibration channel)."""
    from drivers.synthetic import synthesize_capture
    from service.breaker_file import load_breaker

    breaker = load_breaker(BREAKER_FILE)
    cap, _ = synthesize_capture(breaker, "open", dict(breaker.design_parameters()),
                                rng=np.random.default_rng(3))
    return cap


def build_history(Session, capture_dir: Path, *, n_per_breaker: int = 30, drift_from: int = 16,
                  start: datetime | None = None, step: timedelta = timedelta(hours=6)) -> dict:
    """Two breakers: ``leaky`` whose DO falls 3 % per operation from ``drift_from`` on (it alarms),
    and ``control`` which stays healthy. Returns {"breakers": {name: id}, "operations": [ids]}."""
    start = start or datetime(2026, 1, 1, tzinfo=timezone.utc)
    cap = synth_captures()
    rng = np.random.default_rng(7)
    out = {"breakers": {}, "operations": []}
    with Session() as s, s.begin():
        text = BREAKER_FILE.read_text()
        cam = (BREAKER_FILE.parent / "reference-252kV.cam.csv").read_text()
        for name in ("leaky", "control"):
            out["breakers"][name] = crud.upsert_breaker(s, name=name, breaker_file=text, cam_file_name="cam.csv",
                                                        cam_table=cam, tag=name).id
    for i in range(n_per_breaker):
        for name, breaker_id in out["breakers"].items():
            do = 41.0 * (1 + 0.01 * rng.standard_normal())
            if name == "leaky" and i >= drift_from:
                do *= (1 - 0.03 * (i - drift_from + 1))
            out["operations"].append(add_operation(Session, capture_dir, cap, breaker_id=breaker_id,
                                                   key=f"{name}-{i:04d}", at=start + i * step, do=do))
    return out


def add_operation(Session, capture_dir: Path, cap, *, breaker_id: int, key: str, at: datetime, do: float) -> int:
    """One opening: its capture file, its operation row, its fit result (DO given) and the drift
    detector's update, committed as the service does."""
    from service.alarms.settings import DriftSettings
    from service.jobs.fit import update_drift

    path, sha = write_capture_file(cap, capture_dir / at.strftime("%Y") / at.strftime("%m%d"), key)
    with Session() as s, s.begin():
        op, _ = crud.create_operation(s, capture_key=key, breaker_id=breaker_id, kind="open", occurred_at=at,
                                      source="daq", capture_path=str(path.resolve()), capture_sha256=sha,
                                      flags=[], sample_rate=cap.sample_rate, n_samples=int(cap.travel.size))
        params = {"AO": 210.0, "BO": 95.0, "DO": do, "EO": 4.5}
        crud.store_fit_result(s, operation_id=op.id, curve=None,
                              result={"parameters": params, "identifiable": True,
                                      "ci95": {k: [v * 0.995, v * 1.005] for k, v in params.items()}})
        update_drift(s, breaker_id=breaker_id, settings=DriftSettings.from_mapping(ALARMS))
        return op.id
