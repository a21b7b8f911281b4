"""Splitting a CFF (C37.111-2013 combined file) into its CFG, INF, HDR and DAT parts.

Writers vary the section markers (``--- file type: CFG ---``, ``---- FILE TYPE : DAT BINARY :
1234 ----``, ``=== file type: hdr ===``, ``FILE TYPE: CFG``), so any marker made of a line of
dashes or similar around ``file type``, a section name, an optional format and byte count is
accepted.
"""

from __future__ import annotations

import re

from drivers.capture import CaptureError

_MARK = re.compile(
    rb"^\s*(?:[-=*#~_<>\[]{2,}\s*(?:file\s*type\s*[:=]?\s*)?|file\s*type\s*[:=]?\s*)"
    rb"(CFG|HDR|INF|DAT)(?:\s*[:=,]?\s*(ASCII|BINARY32|BINARY|FLOAT32))?\s*(?:[:=,]?\s*(\d+)\s*(?:bytes)?)?"
    rb"\s*[-=*#~_<>\]]*\s*$", re.IGNORECASE)
_STANDARD = re.compile(rb"^--- file type: (CFG|HDR|INF|DAT(?: (?:ASCII|BINARY32|BINARY|FLOAT32)(?:: \d+)?)?) ---$",
                       re.IGNORECASE)


def split_cff(data: bytes, name: str) -> tuple[dict, str | None, list]:
    """Return ``({"CFG": bytes, "DAT": bytes, "HDR": ..., "INF": ...}, dat_format, warnings)``."""
    sections: dict = {}
    warnings: list = []
    fmt = None
    current, start, pos = None, 0, 0
    odd = False
    while pos < len(data):
        nl = data.find(b"\n", pos)
        end = len(data) if nl < 0 else nl
        line = data[pos:end].rstrip(b"\r")
        nxt = end + 1
        m = _MARK.match(line) if len(line) < 120 else None
        if m:
            if current is not None:
                sections[current] = data[start:pos]
            odd |= not _STANDARD.match(line.strip())
            current = m.group(1).decode().upper()
            if current == "DAT":
                fmt = m.group(2).decode().upper() if m.group(2) else _format_of(sections.get("CFG", b""))
                if fmt != "ASCII":
                    body = data[nxt:]
                    if m.group(3):
                        declared = int(m.group(3))
                        if len(body) < declared:
                            warnings.append(f"the DAT section holds {len(body)} of the {declared} bytes "
                                            "its marker declares")
                        body = body[:declared]
                        sections["DAT"] = body
                        current, start, pos = None, nxt + len(body), nxt + len(body)
                        continue
                    sections["DAT"] = body
                    current = None
                    break
            start = nxt
        pos = nxt
    if current is not None:
        sections[current] = data[start:]
    if not sections:
        raise CaptureError(f"{name}: no section marker such as '--- file type: CFG ---' found; "
                           "this is not a COMTRADE CFF file")
    if odd:
        warnings.append("the CFF section markers are not the standard '--- file type: ... ---' form")
    for part in ("CFG", "DAT"):
        if part not in sections:
            raise CaptureError(f"{name}: the CFF file has no {part} section")
    return sections, fmt, warnings


def _format_of(cfg: bytes) -> str | None:
    for line in cfg.splitlines():
        word = line.strip().upper()
        if word in (b"ASCII", b"BINARY", b"BINARY32", b"FLOAT32"):
            return word.decode()
    return None
