"""Text of COMTRADE files: UTF-8 first, then a configured or detected legacy code page.

Relays write channel and station names in the code page of the machine that configured them
(cp1251 in Russia, GBK in China, ISO-8859-1 in Western Europe). The file never says which, so
the choice is made from the bytes: Latin text puts accented letters inside words of ASCII
letters, Cyrillic and Chinese text form whole words of non-ASCII bytes, and Chinese text pairs
bytes into the common (GB2312 level-1) ideographs.
"""

from __future__ import annotations

import codecs
import re

from drivers.capture import CaptureError

LEGACY_ENCODINGS = ("cp1251", "gbk", "iso-8859-1")
_WORD = re.compile(r"[^\W\d_]+")


def decode_text(data: bytes, *, name: str, encoding: str | None = None) -> tuple[str, str]:
    """Decode a text file's bytes.

    Returns ``(text, encoding)``; ``encoding`` is ``ascii``, ``utf-8`` or the legacy code page
    used. ``encoding`` forces a code page. Raises CaptureError naming the file when the forced
    code page does not fit.
    """
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    if encoding:
        try:
            codecs.lookup(encoding)
        except LookupError:
            raise CaptureError(f"{name}: unknown text encoding '{encoding}'") from None
        try:
            return data.decode(encoding), encoding.lower()
        except UnicodeError:
            raise CaptureError(f"{name}: the text is not valid {encoding}") from None
    if data.isascii():
        return data.decode("ascii"), "ascii"
    try:
        return data.decode("utf-8"), "utf-8"
    except UnicodeDecodeError:
        pass
    enc = guess_legacy_encoding(data)
    return data.decode(enc, errors="replace"), enc


def guess_legacy_encoding(data: bytes) -> str:
    """The most plausible of cp1251, GBK and ISO-8859-1 for non-UTF-8 bytes."""
    high = [b for b in data if b >= 0x80]
    if not high:
        return "ascii"
    latin = data.decode("iso-8859-1")
    inside, alone = 0, 0
    for word in _WORD.findall(latin):
        n = sum(1 for c in word if ord(c) >= 0x80)
        if n:
            if any(c.isascii() for c in word):
                inside += n
            else:
                alone += n
    if inside >= alone:
        return "iso-8859-1"
    if _looks_like_gb2312(data):
        return "gbk"
    return "cp1251"


def _looks_like_gb2312(data: bytes) -> bool:
    try:
        data.decode("gbk")
    except UnicodeDecodeError:
        return False
    pairs = common = 0
    i = 0
    while i < len(data):
        b = data[i]
        if b < 0x80:
            i += 1
            continue
        trail = data[i + 1] if i + 1 < len(data) else 0
        pairs += 1
        if 0xB0 <= b <= 0xF7 and 0xA1 <= trail <= 0xFE:
            common += 1
        i += 2
    high = [b for b in data if b >= 0x80]
    # cp1251 lower-case Cyrillic (0xE0-0xFF) dominates Russian text; as GBK lead bytes these fall
    # in the rare level-2 block or outside GB2312 altogether.
    lower = sum(1 for b in high if b >= 0xE0) / max(1, len(high))
    # Upper-case Cyrillic abbreviations (ТН, ЗМН) are all bytes >= 0xC0; Chinese text has a byte
    # below 0xC0 in 3 of 5 characters, so two or more characters without one are not Chinese.
    all_letters = all(b >= 0xC0 for b in high)
    return pairs > 0 and common / pairs >= 0.9 and lower < 0.5 and not (all_letters and pairs >= 2)
