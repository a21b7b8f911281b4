"""Upgrades keep the history: a database built at the first migration with real rows (breakers,
operations, fits, parameter values, alarms, drift states, DAQ status, API keys) is upgraded to
head and every row and API answer is checked. Every migration is also tested against the
revision before it (found by walking Alembic's script directory, so a new migration is covered
without editing this file), including its downgrade.

The rows are written with the columns of the revision they belong to (``SEEDS``), into tables
reflected from the database at that revision, never through today's models.
"""

from __future__ import annotations

import hashlib
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest
from sqlalchemy import MetaData, inspect, select

from service.breaker_file import load_breaker
from service.storage.db import alembic_config, current_revision, downgrade, make_engine, upgrade

REPO = Path(__file__).resolve().parents[2]
BREAKER_TOML = REPO / "config" / "breakers" / "reference-252kV.toml"
CAM_CSV = REPO / "config" / "breakers" / "reference-252kV.cam.csv"
T0 = datetime(2026, 3, 2, 8, 0, tzinfo=timezone.utc)

ADMIN_KEY = "hvcb_upgrade-admin-key-0123456789abcdefghijkl"
READER_KEY = "hvcb_upgrade-reader-key-0123456789abcdefghijk"
REVOKED_KEY = "hvcb_upgrade-revoked-key-0123456789abcdefghij"


def _chain() -> list:
    """Alembic revisions, first to head."""
    from alembic.script import ScriptDirectory

    return list(reversed(list(ScriptDirectory.from_config(alembic_config("sqlite://")).walk_revisions())))


CHAIN = _chain()
FIRST = CHAIN[0].revision
HEAD = CHAIN[-1].revision


# -- the rows, as each revision's schema has them ------------------------------------------------
def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def _drift_state_monitoring() -> dict:
    """A drift detector state as version 1 stores it: monitoring DO with a 20-fit baseline."""
    return {"version": 1, "parameter": "DO", "phase": "monitoring", "collected": [],
            "baseline": {"mean": 41.0, "sd": 0.6, "n": 20, "operation_ids": [1, 3],
                         "excluded_operation_ids": []},
            "s_rising": 0.0, "s_falling": 9.5, "run_rising": [], "run_falling": [5, 7],
            "run_length_rising": 0, "run_length_falling": 2, "level": "alarm", "acknowledged": False,
            "acknowledged_by": None, "acknowledged_at": None, "below_count": 0, "episode": 1,
            "last_operation_id": 7, "last_time": "2026-03-02T14:00:00Z", "last_z": -4.0,
            "last_score": -4.0, "held": None, "outliers_ignored": 0, "fits_monitored": 2}


ALARM_EVIDENCE = {"parameter": "DO", "watched_direction": "falling", "drift_direction": "falling",
                  "baseline": {"mean": 41.0, "sd": 0.6, "n": 20, "operation_ids": [1, 3],
                               "excluded_operation_ids": []},
                  "current": {"operation_id": 7, "time": "2026-03-02T14:00:00Z", "value": 38.6,
                              "ci95": [38.1, 39.1], "stderr": 0.255, "z": -4.0, "change_rel": -0.0585},
                  "statistic": 9.5, "thresholds": {"k": 0.5, "warning": 5.0, "alarm": 8.0, "clear": 1.0},
                  "operation_ids": [5, 7], "run_length": 2}


def seed_initial() -> dict[str, list[dict]]:
    """Rows of revision 0001's tables (its columns exactly)."""
    text, cam = BREAKER_TOML.read_text(), CAM_CSV.read_text()
    digest = hashlib.sha256((text + "\0" + cam).encode()).hexdigest()
    breakers = [dict(id=b, name=name, tag=tag, breaker_file=text, cam_file_name=CAM_CSV.name, cam_table=cam,
                     content_sha256=digest, baseline_reset_at=None, created_at=T0, updated_at=T0)
                for b, name, tag in ((1, "reference-252kV", "Q1"), (2, "bay2-252kV", "Q2"))]
    keys = [dict(id=1, name="admin (generated at first start)", prefix=ADMIN_KEY[:12], key_hash=_sha(ADMIN_KEY),
                 role="admin", created_at=T0, revoked_at=None),
            dict(id=2, name="scada reader", prefix=READER_KEY[:12], key_hash=_sha(READER_KEY), role="reader",
                 created_at=T0, revoked_at=None),
            dict(id=3, name="old laptop", prefix=REVOKED_KEY[:12], key_hash=_sha(REVOKED_KEY), role="operator",
                 created_at=T0, revoked_at=T0 + timedelta(days=1))]
    ops, fits, values = [], [], []
    do_values = {1: 41.2, 3: 40.8, 5: 39.4, 7: 38.6}
    for i in range(1, 9):
        breaker_id = 1 if i <= 7 else 2
        kind = "open" if i % 2 else "close"
        at = T0 + timedelta(hours=i)
        ops.append(dict(id=i, breaker_id=breaker_id, kind=kind, capture_key=f"key{i:04d}", occurred_at=at,
                        received_at=at + timedelta(seconds=2), source="daq" if i != 4 else "upload",
                        capture_path=f"/var/lib/hvcb/captures/2026/0302/key{i:04d}.cfg",
                        capture_sha256=_sha(f"capture {i}"), flags=["decoy_suspect"] if i == 6 else [],
                        sample_rate=128000.0, n_samples=51200))
        status = "queued" if i == 8 else ("failed" if i == 6 else "done")
        fit = dict(id=i, operation_id=i, breaker_id=breaker_id, kind=kind, status=status,
                   attempts=0 if status == "queued" else 1, results_stored=1 if status == "done" else 0,
                   failure_reason="capture unusable: the travel does not move" if status == "failed" else None,
                   parameters=None, ci95=None, stderr=None, rmse_rad=None, fitness=None, window_start_s=None,
                   window_end_s=None, onset_delay_s=None, noise_rad=None, evaluations=None, runtime_s=None,
                   identifiable=None, condition_number=None, dc_used=None, dc_source=None, warnings=None,
                   characteristics=None, curve=None, result=None, worker=None, queued_at=at,
                   started_at=None, finished_at=None)
        if status == "done":
            params = ({"AO": 210.0 + i, "BO": 95.0, "DO": do_values[i], "EO": 4.5} if kind == "open"
                      else {"AC": 180.0, "BC": 0.92, "CC": 12.0 + i})
            ci = {k: [v * 0.99, v * 1.01] for k, v in params.items()}
            fit.update(parameters=params, ci95=ci, stderr={k: v * 0.005 for k, v in params.items()},
                       rmse_rad=0.0021, fitness=1.3e-4, window_start_s=0.012, window_end_s=0.061,
                       onset_delay_s=0.0007, noise_rad=0.0009, evaluations=4200, runtime_s=3.2,
                       identifiable=True, condition_number=57.0,
                       dc_used=212.0 if kind == "close" else None,
                       dc_source="opening fit of operation 1" if kind == "close" else None,
                       warnings=[], characteristics={"operating_time_s": 0.031, "average_speed_rad_s": 21.5},
                       curve={"t": [0.0, 0.05, 0.1], "fitted": [0.0, 0.9, 1.2]},
                       result={"parameters": params, "kind": kind}, worker="node1:4242",
                       started_at=at + timedelta(seconds=3), finished_at=at + timedelta(seconds=6))
            for name, v in params.items():
                values.append(dict(id=len(values) + 1, fit_id=i, operation_id=i, breaker_id=breaker_id, kind=kind,
                                   name=name, value=v, ci_low=ci[name][0], ci_high=ci[name][1], identifiable=True,
                                   occurred_at=at))
        fits.append(fit)
    alarms = [dict(id=1, breaker_id=1, parameter="DO", level="alarm", episode=1, state="raised",
                   message="ALARM: buffer damping factor DO falling (-5.9 % from baseline); likely buffer oil leak",
                   evidence=ALARM_EVIDENCE, operation_id=7, raised_at=T0 + timedelta(hours=7),
                   updated_at=T0 + timedelta(hours=7), acknowledged_at=None, acknowledged_by=None,
                   ack_comment=None, cleared_at=None),
              dict(id=2, breaker_id=1, parameter="BO", level="warning", episode=1, state="cleared",
                   message="WARNING: opening spring factor BO falling", evidence={"operation_ids": [3],
                                                                                 "cleared": {"reason": "back"}},
                   operation_id=3, raised_at=T0 + timedelta(hours=3), updated_at=T0 + timedelta(hours=5),
                   acknowledged_at=T0 + timedelta(hours=4), acknowledged_by="scada reader",
                   ack_comment="checked on site", cleared_at=T0 + timedelta(hours=5))]
    return {"breakers": breakers, "api_keys": keys, "operations": ops, "fits": fits, "parameter_values": values,
            "alarms": alarms,
            "drift_states": [dict(breaker_id=1, parameter="DO", state=_drift_state_monitoring(),
                                  updated_at=T0 + timedelta(hours=7))],
            "daq_status": [dict(breaker_id=1, connected=True, last_seen=T0 + timedelta(hours=8), frames=123456,
                                frames_dropped=3, crc_errors=1, captures=7, detail="modbus tcp 10.0.0.5:502")]}


def seed_diagnoses() -> dict[str, list[dict]]:
    return {"diagnoses": [dict(id=1, operation_id=1, status="done", result={"verdict": "model adequate",
                                                                          "gap_rad": 0.0012},
                               failure_reason=None, requested_at=T0 + timedelta(days=1),
                               finished_at=T0 + timedelta(days=1, seconds=40))]}


def seed_web_sessions() -> dict[str, list[dict]]:
    return {"web_sessions": [dict(id=1, token_hash=_sha("session token"), key_id=1, created_at=T0,
                                  expires_at=T0 + timedelta(hours=8), ended_at=None)]}


def seed_fit_versions() -> dict[str, list[dict]]:
    """A finished refit of breaker 1 that superseded operation 1's first fit."""
    return {"refit_runs": [dict(id=1, breaker_id=1, since=None, status="done", reason="estimator upgrade",
                                requested_by="admin", total=6, done=6, failed=0, created_at=T0 + timedelta(days=2),
                                started_at=T0 + timedelta(days=2), finished_at=T0 + timedelta(days=2, hours=1))],
            "fit_versions": [dict(id=1, fit_id=1, operation_id=1, version=1, status="done", failure_reason=None,
                                  parameters={"AO": 209.0, "BO": 94.0, "DO": 41.5, "EO": 4.4},
                                  ci95={"DO": [41.0, 42.0]}, rmse_rad=0.0025, result={"kind": "open"},
                                  finished_at=T0 + timedelta(hours=1, seconds=6),
                                  superseded_at=T0 + timedelta(days=2, minutes=5), superseded_by_run=1)]}


def seed_capture_previews() -> dict[str, list[dict]]:
    return {"capture_previews": [dict(operation_id=2, pruned_at=T0 + timedelta(days=400), bytes_freed=164295,
                                      preview={"t": [0.0, 0.01, 0.02], "travel": [0.0, 0.4, 1.1],
                                               "vibration": None, "sample_rate": 128000.0, "n_samples": 51200,
                                               "buckets": 100})]}


def seed_alarm_actions() -> dict[str, list[dict]]:
    return {"alarm_actions": [dict(id=1, breaker_id=1, alarm_id=None, action="shelve", by="operator-1",
                                   at=T0 + timedelta(days=3), reason="crew on site",
                                   until=T0 + timedelta(days=3, hours=8))]}


# Revision -> the rows that revision's new tables hold. A migration that adds a table adds its seed.
SEEDS = {"0001": seed_initial, "0002": seed_diagnoses, "0003_web": seed_web_sessions,
         "0004": seed_fit_versions, "0005": seed_capture_previews, "0007": seed_alarm_actions}


# -- helpers -------------------------------------------------------------------------------------
def _tables(engine) -> MetaData:
    md = MetaData()
    md.reflect(engine)
    return md


def _insert(engine, rows: dict[str, list[dict]]) -> None:
    md = _tables(engine)
    with engine.begin() as conn:
        for name, items in rows.items():
            conn.execute(md.tables[name].insert(), items)
    if engine.dialect.name == "postgresql":  # explicit ids: move the sequences past them
        from sqlalchemy import text

        with engine.begin() as conn:
            for name in rows:
                if "id" in md.tables[name].c:
                    conn.execute(text(f"SELECT setval(pg_get_serial_sequence('{name}', 'id'), "
                                      f"(SELECT MAX(id) FROM {name}))"))


def snapshot(engine) -> dict[str, list[dict]]:
    """Every row of every table (but Alembic's), ordered by primary key."""
    md = _tables(engine)
    out = {}
    with engine.connect() as conn:
        for name, table in md.tables.items():
            if name == "alembic_version":
                continue
            order = list(table.primary_key.columns) or list(table.c)
            out[name] = [dict(r._mapping) for r in conn.execute(select(table).order_by(*order))]
    return out


def assert_rows_kept(before: dict, after: dict, *, dropped_ok: bool = False) -> None:
    """Every row of ``before`` is in ``after`` with the same values in the columns both have."""
    for name, rows in before.items():
        if name not in after:
            assert dropped_ok, f"table {name} disappeared"
            continue
        got = after[name]
        assert len(got) == len(rows), f"{name}: {len(rows)} rows before, {len(got)} after"
        for old, new in zip(rows, got):
            common = set(old) & set(new)
            assert set(old) <= set(new) or dropped_ok, f"{name}: columns lost: {set(old) - set(new)}"
            assert {k: old[k] for k in common} == {k: new[k] for k in common}, f"{name}: row changed"


def walk_up(url: str, engine, to: str) -> None:
    """Upgrade one revision at a time from empty to ``to``, seeding each revision's new tables and
    checking no row is lost or changed by any step."""
    for script in CHAIN:
        before = snapshot(engine)
        upgrade(url, script.revision)
        engine.dispose()
        assert_rows_kept(before, snapshot(engine))
        if script.revision in SEEDS:
            _insert(engine, SEEDS[script.revision]())
        if script.revision == to:
            return
    raise AssertionError(f"revision {to} not in the chain")


def _expected() -> dict[str, list[dict]]:
    rows: dict[str, list[dict]] = {}
    for seed in SEEDS.values():
        rows.update(seed())
    return rows


# -- the tests -----------------------------------------------------------------------------------
def test_chain_is_linear_and_seeds_name_real_revisions():
    ids = [s.revision for s in CHAIN]
    assert set(SEEDS) <= set(ids), f"seeds for unknown revisions: {set(SEEDS) - set(ids)}"
    for prev, nxt in zip(CHAIN, CHAIN[1:]):
        assert nxt.down_revision == prev.revision, f"{nxt.revision} does not follow {prev.revision}"


def test_first_migration_upgraded_to_head_keeps_every_row_and_api_answer(empty_db_url, tmp_path):
    engine = make_engine(empty_db_url)
    try:
        walk_up(empty_db_url, engine, HEAD)
        assert current_revision(engine) == HEAD
        got = snapshot(engine)
        for name, rows in _expected().items():
            assert len(got[name]) == len(rows), name
        check_api(empty_db_url, tmp_path)

        downgrade(empty_db_url, "base")
        engine.dispose()
        assert set(inspect(engine).get_table_names()) <= {"alembic_version"}
        assert current_revision(engine) is None
        upgrade(empty_db_url)
        engine.dispose()
        assert current_revision(engine) == HEAD
        assert all(not rows for rows in snapshot(engine).values())
    finally:
        engine.dispose()


@pytest.mark.parametrize("script", CHAIN, ids=[s.revision for s in CHAIN])
def test_migration_against_the_revision_before_it(script, empty_db_url):
    """Upgrade from the previous revision with data, downgrade back, upgrade again: no row lost."""
    engine = make_engine(empty_db_url)
    try:
        if script.down_revision is not None:
            walk_up(empty_db_url, engine, script.down_revision)
        before = snapshot(engine)
        upgrade(empty_db_url, script.revision)
        engine.dispose()
        assert current_revision(engine) == script.revision
        assert_rows_kept(before, snapshot(engine))
        if script.revision in SEEDS:
            _insert(engine, SEEDS[script.revision]())
        with_new = snapshot(engine)

        downgrade(empty_db_url, script.down_revision or "base")
        engine.dispose()
        assert current_revision(engine) == script.down_revision
        assert_rows_kept(before, snapshot(engine))

        upgrade(empty_db_url, script.revision)
        engine.dispose()
        after = snapshot(engine)
        assert_rows_kept(before, after)
        # tables the migration created come back empty: their rows went with the downgrade
        assert set(after) == set(with_new)
    finally:
        engine.dispose()


# -- the API on the upgraded database ------------------------------------------------------------
def _z(t: datetime) -> str:
    return t.astimezone(timezone.utc).isoformat().replace("+00:00", "Z")


def check_api(url: str, tmp_path) -> None:
    from fastapi.testclient import TestClient

    from service.api.app import create_app
    from service.settings import load_settings

    settings = load_settings(data_dir=tmp_path / "api", database_url=url, broker_url="", executor="inline",
                             breakers=[], bootstrap_admin_key=None)
    seed = _expected()
    app = create_app(settings, start_monitor=False, on_key=lambda k: pytest.fail("a new admin key was made"))
    admin, reader = {"X-API-Key": ADMIN_KEY}, {"X-API-Key": READER_KEY}
    with TestClient(app) as client:
        assert client.get("/api/v1/breakers", headers={"X-API-Key": REVOKED_KEY}).status_code == 401

        r = client.get("/api/v1/breakers", headers=reader)
        assert r.status_code == 200, r.text
        assert [(b["id"], b["name"], b["tag"]) for b in r.json()] == \
               [(b["id"], b["name"], b["tag"]) for b in seed["breakers"]]
        detail = client.get("/api/v1/breakers/1", headers=reader).json()
        assert detail["breaker_file"] == BREAKER_TOML.read_text()
        assert detail["design_parameters"] == pytest.approx(
            {k: float(v) for k, v in load_breaker(BREAKER_TOML).design_parameters().items()})

        ops = client.get("/api/v1/breakers/1/operations?limit=100", headers=reader).json()
        want_ops = [o for o in seed["operations"] if o["breaker_id"] == 1]
        assert sorted(o["id"] for o in ops) == [o["id"] for o in want_ops]
        fits = {f["operation_id"]: f for f in seed["fits"]}
        for want in seed["operations"]:
            got = client.get(f"/api/v1/operations/{want['id']}", headers=reader).json()
            assert (got["kind"], got["source"], got["capture_sha256"], got["flags"], got["n_samples"]) == \
                   (want["kind"], want["source"], want["capture_sha256"], want["flags"], want["n_samples"])
            assert got["occurred_at"] == _z(want["occurred_at"])
            fit = fits[want["id"]]
            assert got["fit"]["status"] == fit["status"]
            assert got["fit"]["parameters"] == fit["parameters"]
            assert got["fit"]["failure_reason"] == fit["failure_reason"]

        trend = client.get("/api/v1/breakers/1/parameters?name=DO", headers=reader).json()
        want_do = [v for v in seed["parameter_values"] if v["name"] == "DO" and v["breaker_id"] == 1]
        assert [(p["operation_id"], p["value"], p["ci95"]) for p in trend["points"]] == \
               [(v["operation_id"], v["value"], [v["ci_low"], v["ci_high"]]) for v in want_do]

        alarms = client.get("/api/v1/alarms?state=all", headers=reader).json()
        by_id = {a["id"]: a for a in alarms}
        for want in seed["alarms"]:
            got = by_id[want["id"]]
            assert (got["state"], got["level"], got["message"], got["evidence"], got["operation_id"]) == \
                   (want["state"], want["level"], want["message"], want["evidence"], want["operation_id"])
        health = client.get("/api/v1/breakers/1/health", headers=reader).json()
        assert health["status"] == "alarm"
        assert [a["id"] for a in health["active_alarms"]] == [1]
        assert health["opening"]["operation_id"] == 7
        assert health["opening"]["parameters"]["DO"]["value"] == 38.6

        keys = client.get("/api/v1/keys", headers=admin).json()
        assert [(k["name"], k["role"], k["revoked_at"] is not None) for k in keys] == \
               [(k["name"], k["role"], k["revoked_at"] is not None) for k in seed["api_keys"]]

        diag = client.get("/api/v1/operations/1/diagnosis", headers=reader)
        assert diag.status_code == 200 and diag.json()["result"] == seed["diagnoses"][0]["result"]

        # the upgraded database takes new rows: a new key gets the next id
        r = client.post("/api/v1/keys", headers=admin, json={"name": "after upgrade", "role": "reader"})
        assert r.status_code == 201, r.text
        assert r.json()["id"] == len(seed["api_keys"]) + 1
