"""D2: zip members are inflated in small steps with a cap on the bytes produced; the sizes in
the zip's headers are never trusted."""

from __future__ import annotations

import io
import threading
import zipfile
from pathlib import Path

import httpx
import pytest

from service.jobs.upload import UploadRefused, _inflate, _pair_from_zip

from .zipbomb import lying_zip


def _peak_rss_reset() -> bool:
    try:
        Path("/proc/self/clear_refs").write_text("5")  # resets VmHWM, the peak resident size
        return True
    except OSError:
        return False


def _peak_rss_bytes() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
    raise AssertionError("no VmHWM in /proc/self/status")


def test_inflate_stops_at_the_budget_however_much_the_stream_holds():
    blob = lying_zip(b"x", expands_to=64 << 20, declared=64 << 20)  # honest about 64 MB
    zf = zipfile.ZipFile(io.BytesIO(blob))
    with pytest.raises(UploadRefused) as err:
        _inflate(zf, zf.getinfo("bomb.dat"), 1 << 20)
    assert err.value.status_code == 413


def test_lying_header_fails_its_crc_without_expanding_the_stream():
    blob = lying_zip(b"x", expands_to=256 << 20)  # says 167 kB, holds 256 MB
    with pytest.raises(UploadRefused) as err:
        _pair_from_zip(blob, 32 << 20)
    assert err.value.status_code == 422 and "CRC" in err.value.detail


def test_honest_bomb_is_413_from_its_headers():
    blob = lying_zip(b"x", expands_to=64 << 20, declared=1 << 30)
    with pytest.raises(UploadRefused) as err:
        _pair_from_zip(blob, 32 << 20)
    assert err.value.status_code == 413


def test_lying_bomb_through_the_api_is_refused_with_small_memory_and_healthz_answers(live_server):
    """The acceptance case: a 1 MB zip holding 1 GiB, five at once; /healthz polled meanwhile."""
    if not _peak_rss_reset():
        pytest.skip("this kernel cannot reset the peak RSS (/proc/self/clear_refs)")
    live = live_server()
    blob = lying_zip(b"x", expands_to=1 << 30)
    assert len(blob) < 1_100_000
    before = _peak_rss_bytes()
    statuses, health = [], []
    stop = threading.Event()

    def poll():
        with httpx.Client(base_url=live.base, timeout=30) as c:
            while not stop.is_set():
                health.append(c.get("/healthz").status_code)

    def upload():
        r = httpx.post(f"{live.base}/api/v1/breakers/1/captures", headers=live.h("operator"), timeout=120,
                       files={"files": ("bomb.zip", blob, "application/zip")})
        statuses.append((r.status_code, r.json()["detail"]))

    poller = threading.Thread(target=poll)
    poller.start()
    senders = [threading.Thread(target=upload) for _ in range(5)]
    for t in senders:
        t.start()
    for t in senders:
        t.join()
    stop.set()
    poller.join()
    assert len(statuses) == 5 and all(400 <= s < 500 for s, _ in statuses), statuses
    assert health and set(health) == {200}
    assert _peak_rss_bytes() - before < 300 * 1024 * 1024
