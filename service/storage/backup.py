"""Online backup and restore of a whole installation: the database, the capture files, the spool
and the web/admin secrets, with a manifest.

Consistency while the service runs: the database is copied first (SQLite's online backup API,
or ``pg_dump``, both a single consistent snapshot), then the spool, then the capture files. A
capture file is fsynced before its spool entry and its operation row, so every row and entry in
the snapshot finds its file complete in the copy. Files written after the snapshot are copied
too and are harmless (no row names them). A capture pruned between the snapshot and the copy is
listed in the manifest (``captures.missing``); its preview is in the database.

Restore puts the copy into the configured data directory and database, rewrites the capture
paths (they are absolute) from the old capture directory to the new one, and migrates the
database to this code's head revision.
"""

from __future__ import annotations

import json
import os
import shutil
import sqlite3
import subprocess
import time
from datetime import datetime, timezone
from pathlib import Path

from service.durable import write_durably
from service.errors import UserError
from service.storage.spool import sha256_file

MANIFEST = "manifest.json"
FORMAT = 1
SECRETS = ("web.secret", "admin.key")


def _sqlite_path(url: str) -> Path | None:
    from sqlalchemy.engine import make_url

    u = make_url(url)
    if u.get_backend_name() != "sqlite":
        return None
    if not u.database or u.database == ":memory:":
        raise UserError("an in-memory SQLite database cannot be backed up")
    return Path(u.database)


def _libpq_url(url: str) -> str:
    """The SQLAlchemy URL as pg_dump/pg_restore/psql take it (no +driver)."""
    from sqlalchemy.engine import make_url

    return make_url(url).set(drivername="postgresql").render_as_string(hide_password=False)


def _pg_tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise UserError(f"{name} is not on PATH: install the PostgreSQL client tools of the server's "
                        f"version (Debian: apt install postgresql-client), or follow the manual "
                        f"procedure in docs/operations.md")
    return path


def _counts(url: str) -> dict:
    from sqlalchemy import func, select

    from service.storage.db import current_revision, make_engine
    from service.storage.models import AlarmRow, BreakerRow, FitRow, OperationRow

    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            out = {t.__tablename__: int(conn.scalar(select(func.count()).select_from(t)) or 0)
                   for t in (BreakerRow, OperationRow, FitRow, AlarmRow)}
        out["revision"] = current_revision(engine)
    finally:
        engine.dispose()
    return out


def _copy_tree(src: Path, dst: Path) -> tuple[int, int]:
    """Copy regular files (not *.tmp) from ``src`` to ``dst``; returns (files, bytes)."""
    files = size = 0
    if not src.is_dir():
        return 0, 0
    for root, _, names in os.walk(src):
        for name in names:
            if name.endswith(".tmp"):
                continue  # a write in progress; its final name is copied if it lands in time
            s = Path(root) / name
            d = dst / s.relative_to(src)
            d.parent.mkdir(parents=True, exist_ok=True)
            try:
                shutil.copy2(s, d)
            except FileNotFoundError:  # pruned meanwhile
                continue
            files += 1
            size += d.stat().st_size
    return files, size


# -- backup --------------------------------------------------------------------------------------
def backup(settings, dest: str | Path, *, progress=None) -> dict:
    """Write a consistent copy of the installation under ``dest`` (a new or empty directory)."""
    say = progress or (lambda _m: None)
    dest = Path(dest)
    if dest.exists() and any(dest.iterdir()):
        raise UserError(f"backup destination {dest} is not empty; give a new directory")
    dest.mkdir(parents=True, exist_ok=True)
    url = settings.sqlalchemy_url
    started = time.monotonic()
    created = datetime.now(timezone.utc)
    db_path = _sqlite_path(url)
    if db_path is not None:
        if not db_path.is_file():
            raise UserError(f"no database at {db_path}: nothing to back up")
        out = dest / "hvcb.sqlite3"
        say(f"copying the SQLite database {db_path} (online backup API)")
        src = sqlite3.connect(db_path, timeout=30)
        dst = sqlite3.connect(out)
        try:
            # one step: a single read transaction, so the copy is one snapshot (stepping would
            # restart from scratch after every write by the service, forever under load)
            with dst:
                src.backup(dst)
        finally:
            dst.close()
            src.close()
        database = {"kind": "sqlite", "file": out.name, "sha256": sha256_file(out), "bytes": out.stat().st_size}
        counts = _counts(f"sqlite:///{out.resolve()}")
    else:
        out = dest / "database.pgdump"
        say("dumping the PostgreSQL database (pg_dump, custom format)")
        run = subprocess.run([_pg_tool("pg_dump"), "--format=custom", "--no-owner", "--no-privileges",
                              "--file", str(out), "--dbname", _libpq_url(url)], capture_output=True, text=True)
        if run.returncode != 0:
            raise UserError(f"pg_dump failed: {run.stderr.strip()[:500]}")
        database = {"kind": "postgresql", "file": out.name, "sha256": sha256_file(out), "bytes": out.stat().st_size,
                    "tool": subprocess.run([_pg_tool("pg_dump"), "--version"], capture_output=True,
                                           text=True).stdout.strip()}
        counts = None  # read from the live database right after the dump: close, not exact
    say("copying the spool and the capture files")
    spool_files, _ = _copy_tree(Path(settings.spool_dir), dest / "spool")
    files, size = _copy_tree(Path(settings.capture_dir), dest / "captures")
    for name in SECRETS:
        p = Path(settings.data_dir) / name
        if p.is_file():
            shutil.copy2(p, dest / name)
            os.chmod(dest / name, 0o600)
    missing = _missing_captures(dest, database, settings)
    manifest = {"format": FORMAT, "created_at": created.isoformat().replace("+00:00", "Z"),
                "duration_s": round(time.monotonic() - started, 3),
                "database": database, "rows": counts if counts is not None else _counts(url),
                "capture_dir": str(Path(settings.capture_dir).resolve()),
                "captures": {"files": files, "bytes": size, "missing": missing},
                "spool_entries": spool_files, "secrets": [n for n in SECRETS if (dest / n).exists()]}
    # last, and durably: a backup without its manifest is an unfinished one
    write_durably(dest / MANIFEST, json.dumps(manifest, indent=1))
    return manifest


def _missing_captures(dest: Path, database: dict, settings) -> list[int]:
    """Operations in a SQLite snapshot whose raw capture is neither copied nor pruned."""
    if database["kind"] != "sqlite":
        return []
    root = str(Path(settings.capture_dir).resolve())
    conn = sqlite3.connect(dest / database["file"])
    try:
        pruned = {r[0] for r in conn.execute("SELECT operation_id FROM capture_previews")} \
            if conn.execute("SELECT 1 FROM sqlite_master WHERE name='capture_previews'").fetchone() else set()
        out = []
        for op_id, path in conn.execute("SELECT id, capture_path FROM operations"):
            if op_id in pruned or not path.startswith(root):
                continue
            if not (dest / "captures" / Path(path).relative_to(root)).is_file():
                out.append(op_id)
        return out
    finally:
        conn.close()


# -- restore -------------------------------------------------------------------------------------
def read_manifest(src: Path) -> dict:
    path = Path(src) / MANIFEST
    if not path.is_file():
        raise UserError(f"{src} is not a finished hvcb backup: {MANIFEST} is missing")
    try:
        manifest = json.loads(path.read_text())
    except ValueError:
        raise UserError(f"{path} is not valid JSON: the backup is damaged") from None
    if manifest.get("format") != FORMAT:
        raise UserError(f"{path}: backup format {manifest.get('format')!r} is not supported (expected {FORMAT})")
    db = Path(src) / manifest["database"]["file"]
    if not db.is_file() or sha256_file(db) != manifest["database"]["sha256"]:
        raise UserError(f"{db}: the database copy is missing or does not match the manifest's checksum")
    return manifest


def _empty_dir(path: Path) -> bool:
    return not path.exists() or not any(path.iterdir())


def restore(settings, src: str | Path, *, force: bool = False, progress=None) -> dict:
    """Put the backup at ``src`` into ``settings``' data directory and database."""
    from service.storage.db import upgrade

    say = progress or (lambda _m: None)
    src = Path(src)
    manifest = read_manifest(src)
    url = settings.sqlalchemy_url
    capture_dir, spool_dir = Path(settings.capture_dir), Path(settings.spool_dir)
    if not force and not (_empty_dir(capture_dir) and _empty_dir(spool_dir / "pending")):
        raise UserError(f"{capture_dir} or {spool_dir} already holds files; restore into a new data "
                        f"directory or pass --force to overwrite")
    kind = manifest["database"]["kind"]
    target = _sqlite_path(url)
    if kind == "sqlite" and target is None or kind == "postgresql" and target is not None:
        raise UserError(f"the backup holds a {kind} database but the settings name "
                        f"{'SQLite' if target else 'PostgreSQL'}; point DATABASE_URL at the same kind")
    Path(settings.data_dir).mkdir(parents=True, exist_ok=True)
    if kind == "sqlite":
        if target.exists() and not force:
            raise UserError(f"{target} exists; restore into a new data directory or pass --force")
        say(f"restoring the database to {target}")
        target.parent.mkdir(parents=True, exist_ok=True)
        for extra in (target.with_name(target.name + "-wal"), target.with_name(target.name + "-shm")):
            extra.unlink(missing_ok=True)
        tmp = target.with_suffix(".restoring")
        shutil.copyfile(src / manifest["database"]["file"], tmp)
        os.replace(tmp, target)
    else:
        _restore_pg(url, src / manifest["database"]["file"], force=force, say=say)
    say(f"restoring {manifest['captures']['files']} capture files to {capture_dir}")
    if force and capture_dir.exists():
        shutil.rmtree(capture_dir)
    _copy_tree(src / "captures", capture_dir)
    _restore_spool(src / "spool", spool_dir, manifest["capture_dir"], capture_dir)
    for name in manifest.get("secrets", []):
        shutil.copy2(src / name, Path(settings.data_dir) / name)
        os.chmod(Path(settings.data_dir) / name, 0o600)
    _rewrite_capture_paths(url, manifest["capture_dir"], str(capture_dir.resolve()))
    say("migrating the restored database to this version's schema")
    upgrade(url)
    return manifest


def _restore_pg(url: str, dump: Path, *, force: bool, say) -> None:
    from sqlalchemy import inspect

    from service.storage.db import make_engine

    engine = make_engine(url)
    try:
        tables = inspect(engine).get_table_names()
    finally:
        engine.dispose()
    if tables and not force:
        raise UserError("the target PostgreSQL database is not empty; create a new database or pass --force")
    say("restoring the PostgreSQL database (pg_restore)")
    cmd = [_pg_tool("pg_restore"), "--no-owner", "--no-privileges", "--exit-on-error", "--dbname", _libpq_url(url)]
    if force:
        cmd += ["--clean", "--if-exists"]
    run = subprocess.run(cmd + [str(dump)], capture_output=True, text=True)
    if run.returncode != 0:
        raise UserError(f"pg_restore failed: {run.stderr.strip()[:500]}")


def _restore_spool(src: Path, dst: Path, old_root: str, new_root: Path) -> None:
    for entry in sorted((src / "pending").glob("*.json")) if (src / "pending").is_dir() else []:
        data = json.loads(entry.read_text())
        path = data.get("capture_path", "")
        if path.startswith(old_root):
            data["capture_path"] = str(new_root.resolve()) + path[len(old_root):]
        out = dst / "pending" / entry.name
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(data))


def _rewrite_capture_paths(url: str, old_root: str, new_root: str) -> int:
    """Operations name their capture by absolute path: move the prefix to the new capture dir."""
    if old_root == new_root:
        return 0
    from sqlalchemy import String, func, literal, update

    from service.storage.db import make_engine
    from service.storage.models import OperationRow

    engine = make_engine(url)
    try:
        with engine.begin() as conn:
            res = conn.execute(update(OperationRow)
                               .where(OperationRow.capture_path.startswith(old_root + os.sep, autoescape=True))
                               .values(capture_path=literal(new_root, String) + func.substr(
                                   OperationRow.capture_path, len(old_root) + 1, type_=String)))
            return res.rowcount or 0
    finally:
        engine.dispose()
