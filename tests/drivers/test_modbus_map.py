import zlib

import numpy as np
import pytest

from drivers import modbus_map as mm

HEADER = mm.CaptureHeader(status=1, capture_id=0x0102, channels=2, samples=0x2345,
                          first_sample_index=0x0001_0002_0003_0004, sample_rate_hz=128000,
                          payload_crc32=0xB775AF88, lost_captures=3)
REGS = [1, 1, 0x0102, 2, 0x0000, 0x2345, 0x0001, 0x0002, 0x0003, 0x0004,
        0x0001, 0xF400, 0xB775, 0xAF88, 0, 3]


def test_header_encodes_to_the_register_literal():
    assert mm.encode_header(HEADER) == REGS


def test_header_decodes_from_the_register_literal():
    h = mm.decode_header(REGS)
    assert h == HEADER and h.ready and h.payload_registers == 2 * 0x2345


def test_payload_registers_are_twos_complement_interleaved():
    codes = np.array([[1, -2], [3, -4]], dtype=np.int16)
    assert mm.encode_payload(codes) == [0x0001, 0xFFFE, 0x0003, 0xFFFC]
    assert mm.decode_payload([0x0001, 0xFFFE, 0x0003, 0xFFFC], 2).tolist() == [[1, -2], [3, -4]]
    # The payload CRC covers the same bytes as a serial frame payload.
    assert mm.payload_crc32(codes) == zlib.crc32(bytes.fromhex("0100feff0300fcff"))


def test_block_reads_never_exceed_125_registers():
    assert mm.block_reads(300) == [(256, 125), (381, 125), (506, 50)]
    assert mm.block_reads(125) == [(256, 125)]
    with pytest.raises(ValueError, match="1..125"):
        mm.block_reads(10, max_count=126)


@pytest.mark.parametrize("index,value,match", [(mm.MAP_VERSION_REG, 7, "map version"),
                                               (mm.STATUS, 9, "status"),
                                               (mm.CHANNELS, 1, "travel and vibration"),
                                               (mm.SAMPLES, 0xFFFF, "does not fit"),
                                               (mm.SAMPLE_RATE + 1, 0, None)])
def test_implausible_headers_are_refused(index, value, match):
    regs = list(REGS)
    regs[mm.SAMPLES:mm.SAMPLES + 2] = [0, 1000]
    regs[index] = value
    if match is None:  # sample rate 0x0001_0000 Hz is odd but representable
        assert mm.decode_header(regs).sample_rate_hz == 0x10000
        return
    with pytest.raises(mm.RegisterMapError, match=match):
        mm.decode_header(regs)


def test_odd_payload_is_refused():
    with pytest.raises(mm.RegisterMapError, match="whole number"):
        mm.decode_payload([1, 2, 3], 2)


def test_the_documented_register_map_matches_the_code():
    import tomllib
    from pathlib import Path

    doc = tomllib.loads((Path(__file__).resolve().parents[2] / "config" / "modbus-registers.toml").read_text())
    assert doc["map_version"] == mm.MAP_VERSION and doc["payload_start"] == mm.PAYLOAD_START
    assert doc["payload_max_registers"] == mm.MAX_PAYLOAD_REGISTERS
    for name, reg in doc["registers"].items():
        code_name = {"MAP_VERSION": "MAP_VERSION_REG", "PAYLOAD": "PAYLOAD_START"}.get(name, name)
        assert getattr(mm, code_name) == reg["address"], name
