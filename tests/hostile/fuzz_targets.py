"""Fuzz targets for the three parsers that read what accelrig does not control: the recording reader
(CSV and .npz), the YAML loader (profiles) and the wire-protocol frame parser.

Each target takes bytes (hypothesis draws them, shaped by a seed input so most reach deep into the
parser) and must end in a result or an AccelrigError; any other exception is a finding.  Used by
tests/hostile/test_fuzz.py (a few seconds in every run) and tests/benchmarks/bench_fuzz.py (long runs).
"""

from __future__ import annotations

import io
import json
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

from accelrig.acquisition import protocol as P
from accelrig.errors import AccelrigError
from accelrig.profiles.io import parse_profile_text
from accelrig.recording import load_native, read_csv
from accelrig.safe_yaml import load_yaml

REPO = Path(__file__).resolve().parents[2]
PROFILE_TEXT = (REPO / "profiles" / "example-static_faces-vp.yaml").read_text()
CSV_SEED = ("# accelrig-meta: " + json.dumps({"units": "m/s^2", "nominal_rate": 200.0, "scale": 0.000598,
                                              "gaps": [{"index": 2, "missing": 1, "cause": "link"}]})
            + "\nt,ax,ay,az,theta\n" + "".join(f"{i * 0.005:.3f},0.01,-0.02,9.81,{i * 0.1:.1f}\n" for i in range(8)))


def _npz_seed() -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, t=np.arange(8) / 200.0, acc=np.tile([0.0, 0.0, 9.81], (8, 1)),
             meta_json=np.array(json.dumps({"units": "m/s^2"})))
    return buffer.getvalue()


NPZ_SEED = _npz_seed()


def _frames_seed() -> bytes:
    counts = np.array([[1, -2, 16384]] * 4, dtype="<i2")
    frames = [P.encode_frame(P.DATA, P.data_payload(seq, seq * 4, seq * 2000, counts)) for seq in range(6)]
    frames.append(P.encode_frame(P.ACK, b"\x00"))
    return b"".join(frames)


FRAMES_SEED = _frames_seed()

TOKENS = ["0", "1.5", "-2e3", "nan", "inf", "1e999", "9" * 400, "", " ", '"', '""', ",", "\n", "\r\n", "#",
          "# accelrig-meta: ", "{", "}", "[", "]", '"units"', ":", "\ufeff", "\x00", "t", "ax", "ay", "az", "é"]
YAML_TOKENS = ["&a ", "*a", "[", "]", "{", "}", ": ", "- ", "\n", "  ", "!!python/object ", "!!binary ", "? ",
               "1.0e+999", "9" * 60, "'", '"', "#", "---\n", "...", "<<: ", "x", "1", "null", "~", "\t", "%YAML 1.1\n"]


def mutated(seed: bytes, tokens: list[str]) -> st.SearchStrategy[bytes]:
    """The seed with bytes replaced, inserted, deleted and duplicated, or tokens spliced in."""

    @st.composite
    def build(draw):
        data = bytearray(seed)
        for _ in range(draw(st.integers(0, 8))):
            kind = draw(st.sampled_from(["flip", "insert", "delete", "token", "cut", "repeat"]))
            at = draw(st.integers(0, len(data)))
            if kind == "flip" and data:
                data[min(at, len(data) - 1)] = draw(st.integers(0, 255))
            elif kind == "insert":
                data[at:at] = draw(st.binary(min_size=1, max_size=8))
            elif kind == "delete":
                del data[at:at + draw(st.integers(1, 16))]
            elif kind == "token":
                data[at:at] = draw(st.sampled_from(tokens)).encode("utf-8")
            elif kind == "cut":
                del data[at:]
            elif kind == "repeat":
                data[at:at] = bytes(data[at:at + 64]) * draw(st.integers(1, 50))
        return bytes(data)

    return st.one_of(build(), st.binary(max_size=256))


def csv_target(data: bytes) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "r.csv"
        path.write_bytes(data)
        try:
            rec = read_csv(path)
        except AccelrigError:
            return
        assert np.all(np.isfinite(rec.acc)) and np.all(np.diff(rec.t) > 0)


def npz_target(data: bytes) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "r.npz"
        path.write_bytes(data)
        try:
            rec = load_native(path)
        except AccelrigError:
            return
        assert np.all(np.isfinite(rec.acc)) and rec.acc.shape[1] == 3


def yaml_target(data: bytes) -> None:
    text = data.decode("utf-8", "replace")
    try:
        load_yaml(text)
    except AccelrigError:
        pass
    try:
        parse_profile_text(text)
    except AccelrigError:
        pass


def frames_target(data: bytes) -> None:
    stats = P.LinkStats()
    parser = P.FrameParser(stats)
    step = max(1, len(data) // 7)
    frames = []
    for i in range(0, len(data), step):
        frames += parser.feed(data[i:i + step])
    assert stats.bytes_in == len(data)
    assert len(parser._tail) <= parser.max_encoded   # bounded memory whatever the stream


TARGETS = {
    "CSV reader": (csv_target, mutated(CSV_SEED.encode(), TOKENS)),
    ".npz reader": (npz_target, mutated(NPZ_SEED, ["PK\x03\x04", "\x93NUMPY", "<c16", "|O", "(99999999999,)"])),
    "YAML loader (profiles)": (yaml_target, mutated(PROFILE_TEXT.encode(), YAML_TOKENS)),
    "frame parser": (frames_target, mutated(FRAMES_SEED, ["\x00", "\x01", "\xff" * 8])),
}
