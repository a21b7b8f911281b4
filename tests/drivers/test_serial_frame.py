import struct
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.serial_frame import (OVERHEAD, Frame, FrameDecoder, FrameError, encode_frame,
                                  frame_size)

# sync "HVCB", version 1, 2 channels, 2 samples, sequence 7, first index 1000,
# codes (1, -2), (3, -4), CRC-32 0xB775AF88.
FRAME = bytes.fromhex("48564342" "01" "02" "0200" "07000000" "e803000000000000"
                      "0100" "feff" "0300" "fcff" "88af75b7")
CODES = np.array([[1, -2], [3, -4]], dtype=np.int16)


def test_encode_matches_the_byte_literal():
    assert encode_frame(CODES, sequence=7, first_sample_index=1000) == FRAME
    assert frame_size(2) == len(FRAME) == OVERHEAD + 8


def test_decode_the_byte_literal():
    (frame,) = FrameDecoder().feed(FRAME)
    assert (frame.sequence, frame.first_sample_index, frame.samples) == (7, 1000, 2)
    assert frame.codes.tolist() == [[1, -2], [3, -4]]
    assert frame.end_index == 1002


def test_byte_by_byte_feeding_gives_the_same_frame():
    dec = FrameDecoder()
    out = []
    for b in FRAME + FRAME.replace(b"\x07\x00\x00\x00", b"\x08\x00\x00\x00", 1)[:-4] + b"\x00" * 4:
        out += dec.feed(bytes([b]))
    assert len(out) == 1 and out[0].sequence == 7
    assert dec.crc_errors == 1  # the second frame was edited without fixing its CRC


def test_resynchronises_after_garbage_including_a_false_sync():
    dec = FrameDecoder()
    frames = dec.feed(b"\x00\xffHV" + b"HVCB\x09" + FRAME + b"junk")
    assert [f.sequence for f in frames] == [7]
    assert dec.resyncs >= 1 and dec.skipped_bytes > 0


def test_bad_crc_is_rejected_and_counted():
    bad = bytearray(FRAME)
    bad[22] ^= 0x01
    dec = FrameDecoder()
    assert dec.feed(bytes(bad)) == []
    assert dec.crc_errors == 1 and dec.frames == 0


@pytest.mark.parametrize("offset,value", [(4, 9),      # unknown version
                                          (5, 3),      # 3 channels where 2 are expected
                                          (6, 0)])     # zero samples
def test_absurd_headers_are_rejected(offset, value):
    bad = bytearray(FRAME)
    bad[offset] = value
    dec = FrameDecoder()
    assert dec.feed(bytes(bad)) == []
    assert dec.bad_headers == 1


def test_too_many_samples_is_an_absurd_header():
    head = b"HVCB\x01\x02" + struct.pack("<H", 5000) + bytes(12)
    dec = FrameDecoder(max_samples=4096)
    assert dec.feed(head) == [] and dec.bad_headers == 1


def test_sequence_gap_is_reported_on_the_frame_and_counted():
    dec = FrameDecoder()
    a = encode_frame(CODES, sequence=1, first_sample_index=0)
    c = encode_frame(CODES, sequence=4, first_sample_index=6)
    frames = dec.feed(a + c)
    assert [f.missing_before for f in frames] == [0, 2]
    assert (dec.gaps, dec.dropped_frames) == (1, 2)
    assert frames[1].first_sample_index - frames[0].end_index == 4  # the gap in samples


def test_sequence_wraps_without_a_gap():
    dec = FrameDecoder()
    dec.feed(encode_frame(CODES, sequence=2**32 - 1, first_sample_index=0))
    (f,) = dec.feed(encode_frame(CODES, sequence=0, first_sample_index=2))
    assert f.missing_before == 0 and dec.gaps == 0


def test_encode_refuses_bad_input_clearly():
    with pytest.raises(FrameError, match="shape"):
        encode_frame(np.zeros(4, np.int16), sequence=0, first_sample_index=0)
    with pytest.raises(FrameError, match="int16"):
        encode_frame(np.array([[40000, 0]]), sequence=0, first_sample_index=0)


def _crc_ok(frame: Frame) -> bool:
    wire = encode_frame(frame.codes, sequence=frame.sequence, first_sample_index=frame.first_sample_index)
    return zlib.crc32(wire[:-4]) == struct.unpack("<I", wire[-4:])[0]


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=4000), st.integers(1, 64))
def test_fuzz_random_bytes_never_raise(data, chunk):
    dec = FrameDecoder()
    frames = []
    for k in range(0, len(data), chunk):
        frames += dec.feed(data[k:k + chunk])
    assert all(_crc_ok(f) for f in frames)


def _valid_stream(n_frames: int):
    rng = np.random.default_rng(n_frames)
    frames = [encode_frame(rng.integers(-32768, 32767, (16, 2)).astype(np.int16), sequence=k,
                           first_sample_index=16 * k) for k in range(n_frames)]
    return frames, b"".join(frames)


@settings(max_examples=300, deadline=None)
@given(st.integers(2, 12), st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255),
                                              st.sampled_from(["flip", "insert", "delete"])), max_size=8),
       st.integers(1, 200))
def test_fuzz_corrupted_streams_only_yield_original_frames(n_frames, edits, chunk):
    originals, stream = _valid_stream(n_frames)
    buf = bytearray(stream)
    for pos, byte, kind in edits:
        pos %= max(len(buf), 1)
        if kind == "flip":
            buf[pos] ^= byte or 1
        elif kind == "insert":
            buf.insert(pos, byte)
        elif buf:
            del buf[pos]
    dec = FrameDecoder()
    got = []
    for k in range(0, len(buf), chunk):
        got += dec.feed(bytes(buf[k:k + chunk]))
    wire = {encode_frame(f.codes, sequence=f.sequence, first_sample_index=f.first_sample_index) for f in got}
    assert wire <= set(originals)  # nothing invented, nothing accepted with a bad CRC
    assert len(got) + dec.dropped_frames <= n_frames
    if not edits:
        assert len(got) == n_frames and dec.crc_errors == 0
