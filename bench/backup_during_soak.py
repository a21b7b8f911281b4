"""Backup taken during a soak, restored, and compared with the live service (issue 15).

    python bench/soak.py --operations 10000 --keep &      # prints its data directory
    python bench/backup_during_soak.py --config /tmp/hvcb-soak-XXXX/soak.toml

Runs ``hvcb backup`` against the running soak service, restores it into a new data directory
(and a new SQLite file, or a new PostgreSQL database next to the live one), starts the API on
the restored copy and compares its answers with the live service's for everything the backup
holds: breakers, keys, every operation whose fit had finished at backup time (kind, time,
checksum, flags, fit), the DO/BO trends up to the backup, the alarms raised before it, and the
measured curves of a sample of operations (read from the restored capture files).
Writes bench/results/soak_backup.json (or --out).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", required=True, help="the running soak's soak.toml")
    ap.add_argument("--curves", type=int, default=100, help="operations whose curves are compared")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "soak_backup.json"))
    args = ap.parse_args(argv)

    from fastapi.testclient import TestClient

    from service.api.app import create_app
    from service.cli import main as hvcb
    from service.settings import load_settings
    from service.storage.scratch import scratch_pg_database

    cfg = tomllib.loads(Path(args.config).read_text())
    key = cfg["bootstrap_admin_key"]
    live_base = f"http://{cfg['host']}:{cfg['port']}"
    live_settings = load_settings(args.config)
    tmp = Path(tempfile.mkdtemp(prefix="hvcb-soak-backup-"))
    drop = None
    try:
        dest = tmp / "backup"
        t0 = time.monotonic()
        if hvcb(["backup", str(dest), "--config", args.config]) != 0:
            raise SystemExit("hvcb backup failed")
        backup_s = time.monotonic() - t0
        manifest = json.loads((dest / "manifest.json").read_text())
        overrides = {"data_dir": tmp / "restored"}
        if live_settings.database_url:
            scratch = contextlib.ExitStack()
            overrides["database_url"] = scratch.enter_context(
                scratch_pg_database(live_settings.database_url, "hvcb_soak_restore"))
            drop = scratch.close
        else:
            overrides["database_url"] = f"sqlite:///{tmp / 'restored' / 'hvcb.sqlite3'}"
        restore_cfg = tmp / "restore.toml"
        text = Path(args.config).read_text().split("\n[[acquisition]]")[0]  # no DAQs on the copy
        lines = [ln for ln in text.splitlines() if not ln.startswith(("data_dir", "database_url"))]
        restore_cfg.write_text("\n".join([f'data_dir = "{overrides["data_dir"]}"',
                                          f'database_url = "{overrides["database_url"]}"'] + lines) + "\n")
        t0 = time.monotonic()
        if hvcb(["restore", str(dest), "--config", str(restore_cfg)]) != 0:
            raise SystemExit("hvcb restore failed")
        restore_s = time.monotonic() - t0
        restored_settings = load_settings(restore_cfg)
        app = create_app(restored_settings, start_monitor=False, on_key=lambda k: None)
        h = {"X-API-Key": key}
        with TestClient(app) as copy, httpx.Client(base_url=live_base, headers=h, timeout=60) as live:
            report = compare(copy, live, h, args.curves)
        result = {"backup_s": round(backup_s, 1), "restore_s": round(restore_s, 1),
                  "backup_database_bytes": manifest["database"]["bytes"],
                  "backup_capture_files": manifest["captures"]["files"],
                  "backup_capture_bytes": manifest["captures"]["bytes"],
                  "captures_missing": len(manifest["captures"]["missing"]),
                  "database": "postgresql" if live_settings.database_url else "sqlite", **report}
        out = Path(args.out)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(result, indent=2) + "\n")
        print(json.dumps(result, indent=2))
        return 0 if result["mismatches"] == 0 else 1
    finally:
        if drop:
            drop()
        shutil.rmtree(tmp, ignore_errors=True)


def compare(copy, live, h, n_curves: int) -> dict:
    mismatches: list[str] = []

    def get(client, path):
        r = client.get(path, headers=h)
        r.raise_for_status()
        return r.json()

    def same(what, a, b):
        if a != b:
            mismatches.append(what)

    breakers = get(copy, "/api/v1/breakers")
    same("breakers", breakers, get(live, "/api/v1/breakers"))
    same("keys", get(copy, "/api/v1/keys"), get(live, "/api/v1/keys"))
    ops_compared = points_compared = 0
    finished: list[int] = []
    for b in breakers:
        mine = get(copy, f"/api/v1/breakers/{b['id']}/operations?limit=1000")
        theirs = {o["id"]: o for o in get(live, f"/api/v1/breakers/{b['id']}/operations?limit=1000")}
        for op in mine:  # the newest 1000 of each breaker in the copy
            if op["fit"] and op["fit"]["status"] in ("done", "failed"):
                live_op = theirs.get(op["id"]) or get(live, f"/api/v1/operations/{op['id']}")
                same(f"operation {op['id']}", op, live_op)
                finished.append(op["id"])
                ops_compared += 1
        for name in ("DO", "BO"):
            pts = get(copy, f"/api/v1/breakers/{b['id']}/parameters?name={name}&limit=20000")["points"]
            have = {p["operation_id"] for p in pts}
            lv = [p for p in get(live, f"/api/v1/breakers/{b['id']}/parameters?name={name}&limit=20000")["points"]
                  if p["operation_id"] in have]
            same(f"{name} trend of {b['name']}", pts, lv)
            points_compared += len(pts)
    alarms = get(copy, "/api/v1/alarms?state=all")
    live_alarms = {a["id"]: a for a in get(live, "/api/v1/alarms?state=all")}
    for a in alarms:
        la = live_alarms.get(a["id"])
        if la is None:
            mismatches.append(f"alarm {a['id']} missing live")
        elif la["updated_at"] == a["updated_at"]:
            same(f"alarm {a['id']}", a, la)
        else:  # it moved on after the backup (escalated, acknowledged, cleared): its origin is the same
            same(f"alarm {a['id']} origin", {k: a[k] for k in ("breaker_id", "parameter", "raised_at", "episode")
                                             if k in a},
                 {k: la[k] for k in ("breaker_id", "parameter", "raised_at", "episode") if k in la})
    step = max(1, len(finished) // max(1, n_curves))
    curves = 0
    for op_id in finished[::step][:n_curves]:
        same(f"curve {op_id}", get(copy, f"/api/v1/operations/{op_id}/curve?points=500"),
             get(live, f"/api/v1/operations/{op_id}/curve?points=500"))
        curves += 1
    return {"operations_compared": ops_compared, "trend_points_compared": points_compared,
            "alarms_compared": len(alarms), "curves_compared": curves, "mismatches": len(mismatches),
            "mismatched": mismatches[:20]}


if __name__ == "__main__":
    sys.exit(main())
