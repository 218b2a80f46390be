"""The firmware's plain-C protocol header against the Python implementation.

``firmware/host_test/protocol_check.c`` includes
``firmware/esoarm_rig/esoarm_protocol.h``; it is compiled here with gcc and fed
the shared vectors (``firmware/test_vectors.txt``) and random byte streams.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from esoarm.hardware import protocol as P

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None,
                                reason="gcc not found: the C protocol header is not checked")


@pytest.fixture(scope="module")
def checker(tmp_path_factory) -> Path:
    exe = tmp_path_factory.mktemp("c") / "protocol_check"
    subprocess.run(
        ["gcc", "-std=c99", "-O1", "-Wall", "-Wextra", "-Werror", "-pedantic",
         "-I", str(FIRMWARE / "esoarm_rig"), str(FIRMWARE / "host_test" / "protocol_check.c"),
         "-o", str(exe)],
        check=True, capture_output=True, text=True)
    return exe


def _c_parse(exe: Path, data: bytes) -> list[str]:
    out = subprocess.run([str(exe), "parse"], input=data, capture_output=True, check=True)
    return out.stdout.decode().splitlines()


def _py_parse(data: bytes) -> list[str]:
    parser = P.Parser()
    lines = [f"frame {f.kind:02x} {f.seq} {f.payload.hex() or '-'}" for f in parser.feed(data)]
    lines.append(f"stats {parser.frames} {parser.crc_errors} {parser.header_errors} "
                 f"{parser.skipped} {parser.pending}")
    return lines


def _vectors() -> list[list[str]]:
    return [ln.split() for ln in (FIRMWARE / "test_vectors.txt").read_text().splitlines()
            if ln.strip() and not ln.startswith("#")]


def test_c_encoder_matches_vectors(checker):
    rows = _vectors()
    text = "".join(f"{r[0]} {r[1]} {r[2]}\n" for r in rows)
    out = subprocess.run([str(checker), "encode"], input=text, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == [r[3] for r in rows]


def test_c_parser_decodes_vectors(checker):
    stream = b"".join(bytes.fromhex(r[3]) for r in _vectors())
    assert _c_parse(checker, stream) == _py_parse(stream)
    assert _c_parse(checker, stream)[-1] == f"stats {len(_vectors())} 0 0 0 0"


frames = st.lists(st.sampled_from(P.vector_messages()), max_size=8).map(
    lambda ms: b"".join(P.encode(k, s, *f) for k, s, f in ms))


@st.composite
def streams(draw):
    """Valid frames mixed with random bytes, then some bit flips and a truncation."""
    parts = draw(st.lists(st.one_of(frames, st.binary(max_size=24)), max_size=8))
    data = bytearray(b"".join(parts))
    for _ in range(draw(st.integers(0, 3))):
        if data:
            i = draw(st.integers(0, len(data) - 1))
            data[i] ^= 1 << draw(st.integers(0, 7))
    cut = draw(st.integers(0, len(data)))
    return bytes(data[:cut])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(streams())
def test_c_and_python_parse_alike(checker, data):
    assert _c_parse(checker, data) == _py_parse(data)
