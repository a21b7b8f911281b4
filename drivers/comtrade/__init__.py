"""COMTRADE reading for what relays and recorders write (pure decoding; files in, arrays out)."""

from .record import Record, find_sibling, read_cff_bytes, read_record, read_record_bytes
from .text import decode_text

__all__ = ["Record", "decode_text", "find_sibling", "read_cff_bytes", "read_record", "read_record_bytes"]
