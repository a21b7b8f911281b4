"""A small ASCII COMTRADE (1999) encoder for upload tests."""

from __future__ import annotations

import io
import zipfile

import numpy as np


def comtrade_pair(capture, *, travel_unit="rad", name="rec") -> tuple[bytes, bytes]:
    n = capture.travel.size
    a_t, a_v = 1e-5, 0.05
    t_int = np.round(capture.travel / a_t).astype(np.int64)
    v = capture.vibration if capture.vibration is not None else np.zeros(n)
    v_int = np.round(v / a_v).astype(np.int64)
    cfg = "\n".join([
        f"hvcb-test,{name},1999", "2,2A,0D",
        f"1,travel,,,{travel_unit},{a_t},0,0,-99999,99999,1,1,P",
        f"2,vibration,,,g,{a_v},0,0,-99999,99999,1,1,P",
        "50", "1", f"{capture.sample_rate:g},{n}",
        "01/01/2024,00:00:00.000000", "01/01/2024,00:00:00.000000", "ASCII", "1", ""])
    step_us = 1e6 / capture.sample_rate
    lines = [f"{i + 1},{int(round(i * step_us))},{t_int[i]},{v_int[i]}" for i in range(n)]
    return cfg.encode(), ("\n".join(lines) + "\n").encode()


def zipped(cfg: bytes, dat: bytes, stem="rec") -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(f"{stem}.cfg", cfg)
        zf.writestr(f"{stem}.dat", dat)
    return buf.getvalue()
