"""Uploaded capture files (a COMTRADE .cfg and its .dat, one .cff, or one .zip) into a Capture.

The REST API's upload and the web page's upload form share this. A refusal is an
``UploadRefused`` with the HTTP status it answers with and the reason in words. Nothing here
trusts what the upload says about itself: sizes are counted as bytes arrive and as a zip
inflates (docs/security.md).
"""

from __future__ import annotations

import asyncio
import io
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

from drivers.capture import CaptureError
from service.storage import crud
from service.storage.models import utcnow


class UploadRefused(ValueError):
    """An upload that is not stored: ``status_code`` (413 too large, 422 unreadable) and ``detail``."""

    def __init__(self, status_code: int, detail: str):
        super().__init__(detail)
        self.status_code = status_code
        self.detail = detail


async def read_capped(upload, budget: int) -> bytes:
    """The bytes of one uploaded file (anything with an async ``read``), refused past ``budget``."""
    data = await upload.read(budget + 1)
    if len(data) > budget:
        raise UploadRefused(413, f"upload larger than the {budget} byte limit")
    return data


ZIP_CHUNK = 64 * 1024  # bytes produced per decompression step: memory per step is bounded by this
MAX_ZIP_MEMBERS = 64


def _inflate(zf: zipfile.ZipFile, info: zipfile.ZipInfo, budget: int) -> bytes:
    """A member's bytes, decompressed in steps of ZIP_CHUNK and cut at ``budget`` bytes produced.
    The sizes written in the zip's headers are not trusted: a member that expands beyond what
    its header says fails its CRC (422), one that expands beyond the budget is refused (413)."""
    out = bytearray()
    with zf.open(info) as fh:
        while chunk := fh.read(ZIP_CHUNK):
            out += chunk
            if len(out) > budget:
                raise UploadRefused(413, f"the archive expands beyond the {budget} byte limit")
    return bytes(out)


def _pair_from_zip(blob: bytes, cap: int) -> tuple[bytes, bytes, str]:
    try:
        zf = zipfile.ZipFile(io.BytesIO(blob))
        infos = [i for i in zf.infolist() if not i.is_dir()]
    except (zipfile.BadZipFile, ValueError, OSError) as exc:
        raise UploadRefused(422, f"not a readable zip archive: {exc}") from None
    if len(infos) > MAX_ZIP_MEMBERS:
        raise UploadRefused(422, f"the zip holds {len(infos)} files; a capture is a .cfg and its .dat")
    if sum(i.file_size for i in infos) > cap:  # an honest header is refused at once
        raise UploadRefused(413, f"the archive expands beyond the {cap} byte limit")
    cfgs = [i for i in infos if i.filename.lower().endswith(".cfg")]
    if len(cfgs) != 1:
        raise UploadRefused(422, f"the zip must hold exactly one .cfg file, found {len(cfgs)}")
    stem = cfgs[0].filename[:-4]
    dats = [i for i in infos if i.filename[:-4] == stem and i.filename.lower().endswith(".dat")]
    if len(dats) != 1:
        raise UploadRefused(422, f"the zip holds no .dat file matching {cfgs[0].filename}")
    try:
        cfg = _inflate(zf, cfgs[0], cap)
        dat = _inflate(zf, dats[0], cap - len(cfg))
    except (zipfile.BadZipFile, RuntimeError, OSError, ValueError, EOFError, zlib.error) as exc:
        raise UploadRefused(422, f"cannot extract the archive: {exc}") from None
    return cfg, dat, Path(cfgs[0].filename).name


def content_hash(cfg: bytes, dat: bytes) -> str:
    """The capture's content hash: SHA-256 over the hex SHA-256 of the .cfg then the .dat
    (``service.storage.spool.capture_digest`` of the two files)."""
    import hashlib

    return hashlib.sha256(hashlib.sha256(cfg).hexdigest().encode() + hashlib.sha256(dat).hexdigest().encode()
                          ).hexdigest()


@dataclass(frozen=True)
class Upload:
    """An accepted upload: the capture read with the breaker's channel names, and the files as
    sent ({".cfg": bytes, ".dat": bytes} or {".cff": bytes}), stored byte for byte."""

    capture: object
    kind: str
    files: dict | None  # None: a text record, stored as the operations cut from it
    name: str
    more: tuple = ()  # further (capture, kind) of the same record (a CO record's opening)

    @property
    def operations(self) -> tuple:
        """Every (capture, kind) this upload stores, in the record's order."""
        return ((self.capture, self.kind),) + tuple(self.more)


def capture_from_upload(blobs: dict[str, bytes], row, operation: str | None, cap_bytes: int,
                        idempotency_key: str | None = None) -> Upload:
    """The upload read from files {lower-case name: bytes}: a .cfg and its .dat, or one .cff,
    or one .zip holding a .cfg and its .dat. Raises UploadRefused (413/422) with the reason in
    words. CPU and memory heavy: call it off the event loop
    (``parse_upload``)."""
    from service.acquisition.capture_file import load_comtrade_bytes

    names = list(blobs)
    if len(names) == 1 and names[0].endswith((".csv", ".txt")):
        return _text_capture_upload(blobs[names[0]], names[0], row, operation, idempotency_key)
    if len(names) == 1 and names[0].endswith(".zip"):
        cfg, dat, name = _pair_from_zip(blobs[names[0]], cap_bytes)
    elif len(names) == 1 and names[0].endswith(".cff"):
        cfg, dat, name = blobs[names[0]], None, names[0]
    else:
        cfg_names = [n for n in names if n.endswith(".cfg")]
        dat_names = [n for n in names if n.endswith(".dat")]
        if len(cfg_names) != 1 or len(dat_names) != 1 or len(names) != 2:
            raise UploadRefused(422, "send a COMTRADE .cfg and its .dat (two files), one .cff, "
                                     "one .zip holding a .cfg and its .dat, or one analyser export (.csv)")
        cfg, dat, name = blobs[cfg_names[0]], blobs[dat_names[0]], cfg_names[0]
    name = Path(name).name
    if idempotency_key is not None and content_hash(cfg, dat or b"") != idempotency_key:
        raise UploadRefused(422, "the Idempotency-Key is not the content hash of the uploaded .cfg and .dat "
                                 "(damaged in transit, or the wrong key)")
    breaker = crud.breaker_model(row)
    try:
        # the same reader as hvcb fit/detect/inspect: the same message for the same file
        capture = load_comtrade_bytes(cfg, dat, source=f"upload:{name}",
                                      travel_channel=breaker.channels.get("travel", "travel"),
                                      vibration_channel=breaker.channels.get("vibration", "vibration"),
                                      temperature_channel=breaker.channels.get("temperature"))
        if capture.travel.size < 16:
            raise CaptureError(f"{name}: the record holds fewer than 16 samples")
        from service.jobs.ingest import infer_operation

        kind = operation or infer_operation(capture)
    except CaptureError as exc:
        named = name.rsplit(".", 1)[0] + "." in str(exc)  # the reader names the .cfg or the .dat
        raise UploadRefused(422, str(exc) if named else f"{name}: {exc}") from None
    except UploadRefused:
        raise
    except Exception:  # a reader bug must not become a 500 for the client; the reader checks its input
        raise UploadRefused(422, f"{name}: the capture could not be read as COMTRADE") from None
    files = {".cff": cfg} if dat is None else {".cfg": cfg, ".dat": dat}
    return Upload(capture, kind, files, name)


def _text_capture_upload(data: bytes, name: str, row, operation: str | None, idempotency_key: str | None):
    """One text capture (a breaker-analyser export, or a CSV t_s,travel_rad[,vibration_g]) through
    the same reader as the CLI; an analyser record's operations are cut out here, each stored
    as its own operation (``operation`` keeps only that kind)."""
    from service.acquisition.capture_file import breaker_reading, load_capture_bytes
    from service.estimation.record import upload_operations

    if idempotency_key is not None and content_hash(data, b"") != idempotency_key:
        raise UploadRefused(422, "the Idempotency-Key is not the content hash of the uploaded file "
                                 "(damaged in transit, or the wrong key)")
    breaker = crud.breaker_model(row)
    try:
        record = load_capture_bytes(data, name=name, **breaker_reading(breaker))
        from service.jobs.ingest import infer_operation

        ops = []
        for capture, kind in upload_operations(record, breaker, operation):
            if capture.travel.size < 16:
                raise CaptureError(f"{name}: the record holds fewer than 16 samples")
            ops.append((capture, kind or infer_operation(capture)))
    except ValueError as exc:  # CaptureError, FitError: the reader's words
        raise UploadRefused(422, str(exc) if name in str(exc) else f"{name}: {exc}") from None
    except Exception:  # a reader bug must not become a 500 for the client
        raise UploadRefused(422, f"{name}: the capture could not be read") from None
    # Each operation cut from the record is stored in hvcb's COMTRADE with every recorded channel,
    # the analyser's own results in its .hdr (service.acquisition.comtrade_writer): files=None.
    return Upload(ops[0][0], ops[0][1], None, name, more=tuple(ops[1:]))


async def parse_upload(state, files, row, operation: str | None, idempotency_key: str | None = None) -> Upload:
    """Read the uploaded files (anything with an async ``read``) into memory and
    ``capture_from_upload`` them on a worker thread, at most ``[server] upload_parsers`` uploads at
    once: the event loop (and /healthz) never waits for a parse, and the memory of uploads in
    flight is bounded (docs/security.md); uploads waiting their turn stay in the form parser's
    temporary files. ``state``: the app's state (settings, upload_slots)."""
    cap_bytes = state.settings.max_upload_bytes
    if state.upload_slots is None:
        state.upload_slots = asyncio.Semaphore(state.settings.server.upload_parsers)
    async with state.upload_slots:
        blobs, budget = {}, cap_bytes
        for f in files:
            data = await read_capped(f, budget)
            budget -= len(data)
            blobs[(f.filename or "").lower()] = data
        return await asyncio.to_thread(capture_from_upload, blobs, row, operation, cap_bytes, idempotency_key)


def operation_key(key: str, k: int) -> str:
    """The capture key of a record's ``k``-th operation (0: ``key`` itself; then a SHA-256 of
    it and ``k``, 64 hex digits like an Idempotency-Key): a retried CO upload finds both."""
    import hashlib

    return key if k == 0 else hashlib.sha256(f"{key}:{k}".encode()).hexdigest()


def further_operations(session, key: str) -> list:
    """The operations stored after the first from the record uploaded under ``key``."""
    out, k = [], 1
    while (op := crud.get_operation_by_key(session, capture_key=operation_key(key, k))) is not None:
        out.append(op)
        k += 1
    return out


def ingest_upload(monitor, settings, upload: Upload, *, breaker_id: int, source: str, capture_key: str | None):
    """Store the files as sent (fsynced) and hand the operations to the monitor (worker thread).
    Every operation is durable before this returns; the first one's result comes back, the
    others' in its ``more``."""
    from dataclasses import replace

    from service.storage.spool import Spool, write_capture_bytes

    key = capture_key or Spool.new_key()
    if upload.files is None:
        results = []
        first_meta = upload.capture.meta
        for k, (capture, kind) in enumerate(upload.operations):
            for m in ("temperature_c", "temperature_source"):  # one record, one temperature
                if m in first_meta:
                    capture.meta[m] = first_meta[m]
            results.append(monitor.ingest(capture, breaker_id=breaker_id, operation=kind, source=source,
                                          capture_key=operation_key(key, k)))
        return replace(results[0], more=tuple(results[1:]))
    now = utcnow()
    path = write_capture_bytes(upload.files, settings.capture_dir / now.strftime("%Y") / now.strftime("%m%d"), key)
    return monitor.ingest(upload.capture, breaker_id=breaker_id, operation=upload.kind, source=source,
                          capture_path=path, capture_key=key)
