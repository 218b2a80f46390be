"""Framing and parser of the rig protocol (esoarm.hardware.protocol), fuzzed."""

from __future__ import annotations

import struct
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from esoarm.hardware import protocol as P

VECTORS = Path(__file__).resolve().parents[2] / "firmware" / "test_vectors.txt"


def test_crc_is_ccitt_false_check_value():
    # the catalogue check value of CRC-16/CCITT-FALSE over "123456789"
    assert P.crc16(b"123456789") == 0x29B1


def _vector_rows():
    rows = []
    for line in VECTORS.read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        kind, seq, payload, frame, name = line.split()
        rows.append((int(kind, 16), int(seq), bytes.fromhex("" if payload == "-" else payload),
                     bytes.fromhex(frame), name))
    return rows


def test_vector_file_matches_encoder():
    rows = _vector_rows()
    assert len(rows) == len(P.vector_messages())
    for (kind, seq, fields), (vkind, vseq, payload, frame, name) in zip(
            P.vector_messages(), rows, strict=True):
        assert (kind, seq, P.NAMES[kind]) == (vkind, vseq, name)
        assert struct.pack(P.FORMATS[kind], *fields) == payload
        assert P.encode(kind, seq, *fields) == frame


def test_every_type_has_a_vector():
    assert {k for k, _, _ in P.vector_messages()} == set(P.FORMATS)


def test_vectors_decode():
    parser = P.Parser()
    stream = b"".join(r[3] for r in _vector_rows())
    frames = parser.feed(stream)
    assert [(f.kind, f.seq, f.payload) for f in frames] == [
        (k, s, p) for k, s, p, _, _ in _vector_rows()]
    assert parser.bad_frames == 0 and parser.skipped == 0 and parser.pending == 0


def test_torque_roundtrips_float64_bits():
    for u in (0.1, -1.2345678901234567, 1e-300, 2.0 / 3.0):
        (frame,) = P.Parser().feed(P.encode(P.TORQUE, 0, 5, u))
        assert frame.fields() == (5, u)


def test_bad_length_for_type_is_rejected():
    good = bytearray(P.encode(P.STOP, 0))
    bad = bytearray(good)
    bad[4] = 3  # STOP has no payload
    parser = P.Parser()
    assert parser.feed(bytes(bad) + bytes(good)) == [P.Frame(P.STOP, 0, b"")]
    assert parser.header_errors == 1


# -- fuzzing -----------------------------------------------------------------

messages = st.sampled_from(P.vector_messages())
frame_lists = st.lists(messages, min_size=1, max_size=12).map(
    lambda ms: [P.encode(k, s, *f) for k, s, f in ms])


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=400))
def test_random_bytes_never_raise(data):
    parser = P.Parser()
    frames = parser.feed(data)
    # everything it returns is a well-formed frame of a known type
    for f in frames:
        assert len(f.payload) == P.PAYLOAD_SIZES[f.kind]
        f.fields()
    assert parser.skipped + parser.pending + sum(
        P.HEADER_SIZE + len(f.payload) + P.CRC_SIZE for f in frames) == len(data)


@settings(max_examples=200, deadline=None)
@given(frame_lists, st.data())
def test_split_points_do_not_matter(frames, data):
    stream = b"".join(frames)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    parser = P.Parser()
    got = []
    prev = 0
    for c in [*cuts, len(stream)]:
        got += parser.feed(stream[prev:c])
        prev = c
    assert got == P.Parser().feed(stream)
    assert len(got) == len(frames)


@settings(max_examples=200, deadline=None)
@given(frame_lists, st.data())
def test_truncation_keeps_complete_frames(frames, data):
    stream = b"".join(frames)
    cut = data.draw(st.integers(0, len(stream)))
    parser = P.Parser()
    got = parser.feed(stream[:cut])
    complete = 0
    total = 0
    for f in frames:
        total += len(f)
        if total <= cut:
            complete += 1
    assert len(got) == complete
    assert parser.bad_frames == 0
    # the rest arrives later: nothing lost
    assert len(got) + len(parser.feed(stream[cut:])) == len(frames)


@settings(max_examples=300, deadline=None)
@given(frame_lists, st.data())
def test_a_bit_flip_loses_only_its_frame(frames, data):
    i = data.draw(st.integers(0, len(frames) - 1))
    bit = data.draw(st.integers(0, 8 * len(frames[i]) - 1))
    damaged = bytearray(frames[i])
    damaged[bit // 8] ^= 1 << (bit % 8)
    stream = b"".join(frames[:i]) + bytes(damaged) + b"".join(frames[i + 1:])
    parser = P.Parser()
    got = parser.feed(stream)
    expected = [P.Parser().feed(f)[0] for j, f in enumerate(frames) if j != i]
    assert got == expected
    if bit // 8 >= 2:  # past the sync bytes: the candidate is seen and rejected
        assert parser.bad_frames >= 1


@settings(max_examples=200, deadline=None)
@given(frame_lists, st.lists(st.binary(max_size=30), min_size=1, max_size=12))
def test_garbage_between_frames_is_skipped(frames, garbage):
    # garbage without sync bytes cannot hide a frame
    garbage = [g.replace(b"\xa5", b"\x00") for g in garbage]
    stream = b"".join(g + f for g, f in zip(garbage, frames, strict=False))
    got = P.Parser().feed(stream)
    n = min(len(garbage), len(frames))
    assert got == [P.Parser().feed(f)[0] for f in frames[:n]]
