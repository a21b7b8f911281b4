"""A stored fleet history for refit tests and bench/refit_speed.py: operations whose fits are
done (version 1), cycling over a few synthetic captures of the reference breaker."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np
from sqlalchemy import insert, select

from service.storage import crud
from service.storage.models import FitRow, OperationRow, ParameterValueRow, utcnow
from service.storage.spool import write_capture_file

BREAKER_FILE = Path(__file__).resolve().parents[2] / "config" / "breakers" / "reference-252kV.toml"
START = datetime(2026, 1, 1, tzinfo=timezone.utc)


def distinct_captures(breaker, per_kind: int = 3):
    """Synthetic openings and closings with parameters a few per cent apart and their own noise."""
    from drivers.synthetic import synthesize_capture

    out = []
    for kind in ("open", "close"):
        for i in range(per_kind):
            p = dict(breaker.design_parameters())
            for k in ("AO", "BO", "DO", "AC", "CC"):
                p[k] *= 1.0 + 0.01 * (i - per_kind // 2)
            cap, _ = synthesize_capture(breaker, kind, p, rng=np.random.default_rng(100 + 10 * i + (kind == "close")))
            out.append((kind, cap))
    return out


def seed_history(Session, breaker, captures_dir: Path, n: int, *, per_kind: int = 3) -> list[int]:
    """Store ``n`` operations, half openings and half closings in alternation, one hour apart,
    each with a finished fit (version 1). Returns their ids in time order."""
    from service.estimation import fit_capture

    with Session() as s, s.begin():
        breaker_id = crud.register_breaker_file(s, path=BREAKER_FILE).id
    stored = {"open": [], "close": []}
    for i, (kind, cap) in enumerate(distinct_captures(breaker, per_kind)):
        path, sha = write_capture_file(cap, captures_dir, f"{kind}-{i}")
        result = fit_capture(cap, breaker, kind, seed=1).to_dict()
        stored[kind].append((str(path), sha, cap, _plain(result)))
    ops = []
    for k in range(n):
        kind = "open" if k % 2 == 0 else "close"
        path, sha, cap, _ = stored[kind][(k // 2) % len(stored[kind])]
        ops.append(dict(capture_key=f"history-{k}", breaker_id=breaker_id, kind=kind,
                        occurred_at=START + timedelta(hours=k), source="test", capture_path=path,
                        capture_sha256=sha, flags=[], sample_rate=float(cap.sample_rate),
                        n_samples=int(cap.t.size)))
    with Session() as s, s.begin():
        s.execute(insert(OperationRow), ops)
        rows = s.execute(select(OperationRow.id, OperationRow.kind, OperationRow.capture_key)
                         .where(OperationRow.capture_key.like("history-%"))).all()
        by_key = {key: (op_id, kind) for op_id, kind, key in rows}
        fits, now = [], utcnow()
        for k in range(n):
            op_id, kind = by_key[f"history-{k}"]
            result = stored[kind][(k // 2) % len(stored[kind])][3]
            fits.append(dict(operation_id=op_id, breaker_id=breaker_id, kind=kind, status="done",
                             attempts=1, results_stored=1, parameters=result["parameters"],
                             ci95=result["ci95"], stderr=result["stderr"], rmse_rad=result["rmse_rad"],
                             noise_rad=result["noise_rad"], onset_delay_s=result["onset_delay_s"],
                             identifiable=result["identifiable"], result=result, finished_at=now,
                             version=1))
        s.execute(insert(FitRow), fits)
        fit_ids = dict(s.execute(select(FitRow.operation_id, FitRow.id)).all())
        values = []
        for k in range(n):
            op_id, kind = by_key[f"history-{k}"]
            result = stored[kind][(k // 2) % len(stored[kind])][3]
            for name, value in result["parameters"].items():
                lo, hi = result["ci95"][name]
                values.append(dict(fit_id=fit_ids[op_id], operation_id=op_id, breaker_id=breaker_id,
                                   kind=kind, name=name, value=value, ci_low=lo, ci_high=hi,
                                   identifiable=True, occurred_at=START + timedelta(hours=k)))
        s.execute(insert(ParameterValueRow), values)
    return [by_key[f"history-{k}"][0] for k in range(n)]


def _plain(obj):
    from service.jobs.fit import _jsonable

    return _jsonable(obj)
