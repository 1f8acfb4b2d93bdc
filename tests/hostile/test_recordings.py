"""Hostile recordings: CSV and .npz files through the one reader, under memory and time limits."""

from __future__ import annotations

import io
import json
import tracemalloc
import zipfile

import numpy as np
import pytest

import accelrig.recording as recording
from accelrig.recording import Recording, load_recording, save_native, write_csv
from hostile.support import assert_refused, snapshot

GOOD_ROWS = "".join(f"{i * 0.005:.3f},0.01,-0.02,9.81\n" for i in range(400))
META = {"units": "m/s^2", "nominal_rate": 200.0}


def _csv(meta=None, header="t,ax,ay,az", rows=GOOD_ROWS) -> str:
    head = f"# accelrig-meta: {json.dumps(meta)}\n" if meta is not None else ""
    return head + header + "\n" + rows


CSV_CASES: dict[str, tuple[str | bytes, str]] = {
    "units a number": (_csv({"units": 5}), "metadata units: expected a string"),
    "units unknown": (_csv({"units": "furlongs"}), "metadata units"),
    "metadata a list": ('# accelrig-meta: [1, 2]\n' + _csv(), "metadata must be a JSON object"),
    "metadata null": ('# accelrig-meta: null\n' + _csv(), "metadata must be a JSON object"),
    "rate a string": (_csv({"delivered_rate": "fast"}), "metadata delivered_rate"),
    "negative scale": (_csv({"scale": -1}), "metadata scale"),
    "gaps a number": (_csv({"gaps": 5}), "metadata gaps"),
    "gap index a string": (_csv({"gaps": [{"index": "x", "missing": 3}]}), r"metadata gaps\[0\]\.index"),
    "who_am_i 300": (_csv({"who_am_i": 300}), "metadata who_am_i"),
    "5000-digit integer in metadata": ('# accelrig-meta: {"scale": ' + "9" * 5000 + "}\n" + _csv(),
                                       "metadata comment cannot be read"),
    "deep metadata": ('# accelrig-meta: ' + "[" * 100000 + "]" * 100000 + "\n" + _csv(), "metadata"),
    "metadata not JSON": ("# accelrig-meta: {units: g}\n" + _csv(), "not valid JSON"),
    "NaN": (_csv(rows=GOOD_ROWS + "2.1,nan,0,9.8\n"), "row 401 of the data holds a NaN"),
    "inf": (_csv(rows=GOOD_ROWS + "2.1,0,inf,9.8\n"), "NaN or infinite.*column ay"),
    "integer beyond float": (_csv(rows=GOOD_ROWS + "2.1,0,0," + "9" * 400 + "\n"), "NaN or infinite"),
    "4300-digit value": (_csv(rows=GOOD_ROWS + "2.1,0,0," + "9" * 5000 + "\n"), "NaN or infinite"),
    "complex": (_csv(rows=GOOD_ROWS + "2.1,0,1+2j,9.8\n"), "'1\\+2j' is not a number"),
    "field over the csv limit": (_csv(rows=GOOD_ROWS + '2.1,0,"' + "1" * 200_000 + '",9.8\n'), "not a CSV row"),
    "one endless line": ("t,ax,ay,az\n" + "1," * 9_000_000, "line longer than"),
    "NUL bytes": (_csv(rows="0,0,0,9.8\n\x00\x00\x00\n"), "NUL bytes"),
    "latin-1": ("t,ax,ay,az\n0,0,0,9.8\n# caf\xe9\n".encode("latin-1"), "not a text file"),
    "t in milliseconds": (_csv(rows="".join(f"{i * 5},0,0,9.81\n" for i in range(400))), "milliseconds"),
    "t going back": (_csv(rows="0,0,0,9.8\n0.01,0,0,9.8\n0.005,0,0,9.8\n"), "does not increase"),
    "too few values": (_csv(rows="0,0,0\n"), "expected 4 values"),
    "header of numbers": ("0,0,0,9.8\n", "first row holds numbers"),
    "header only": ("t,ax,ay,az\n", "no data rows"),
    "empty": ("", "empty file"),
    "binary": (bytes(range(256)) * 4, "not a text file|NUL"),
    "duplicate column": ("t,ax,ay,az,ax\n0,0,0,9.8,1\n", "appear twice"),
}


@pytest.mark.parametrize("case", sorted(CSV_CASES))
def test_hostile_csv_is_refused(case, guarded, tmp_path):
    content, cause = CSV_CASES[case]
    path = tmp_path / "rec.csv"
    path.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))
    before = snapshot(tmp_path)
    assert_refused(guarded("calibrate", "static", path, "-o", tmp_path / "p.yaml"), cause)
    assert snapshot(tmp_path) == before


def test_a_bom_is_dropped_so_t_is_read(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_bytes(b"\xef\xbb\xbf" + _csv().encode())
    rec = load_recording(path)
    assert rec.t[1] == pytest.approx(0.005)


def test_a_csv_is_streamed_memory_is_the_numbers_not_the_text(tmp_path):
    rows = 20_000
    path = tmp_path / "big.csv"
    t = np.arange(rows) / 200.0
    np.savetxt(path, np.column_stack([t, np.zeros(rows), np.zeros(rows), np.full(rows, 9.81)]), delimiter=",",
               fmt="%.9f", header="t,ax,ay,az", comments="")
    tracemalloc.start()
    try:
        rec = load_recording(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    numbers = rows * 4 * 8
    assert len(rec) == rows
    # whole text + a list of Python floats (the old reader) was ~8x the numbers; streamed it is the
    # float64 buffer, the acc copy and the Recording's arrays
    assert peak < 3.5 * numbers, f"peak {peak / 1e6:.1f} MB for {numbers / 1e6:.1f} MB of numbers"


def test_a_csv_beyond_the_bound_is_refused_where_it_crosses_it(guarded, tmp_path, monkeypatch):
    monkeypatch.setattr(recording, "MAX_VALUES", 1000)
    path = tmp_path / "long.csv"
    path.write_text(_csv())
    assert_refused(guarded("calibrate", "static", path), r"rec|long\.csv:252: more than 1000 values")


# ------------------------------------------------------------------ .npz


def _npy_bytes(array) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=True)
    return buffer.getvalue()


def _npz(path, members: dict[str, bytes], compression=zipfile.ZIP_STORED) -> None:
    with zipfile.ZipFile(path, "w", compression) as z:
        for name, data in members.items():
            z.writestr(name + ".npy", data)


def _good_members(n=400) -> dict[str, bytes]:
    t = np.arange(n) / 200.0
    acc = np.tile([0.0, 0.0, 9.81], (n, 1))
    return {"t": _npy_bytes(t), "acc": _npy_bytes(acc), "meta_json": _npy_bytes(np.array(json.dumps(META)))}


def _declaring(shape, dtype="<f8") -> bytes:
    """An .npy header declaring ``shape`` followed by a few bytes: 884 bytes that claim terabytes."""
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buffer.getvalue() + b"\0" * 64


def _bomb(path):
    """A deflate bomb: acc.npy inflating to 96 MiB from ~100 KiB (what the bound is checked against)."""
    members = _good_members()
    header = io.BytesIO()
    n = 96 * 2**20 // 24
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (n, 3)})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("t.npy", members["t"])
        z.writestr("meta_json.npy", members["meta_json"])
        with z.open("acc.npy", "w", force_zip64=True) as fh:
            fh.write(header.getvalue())
            zeros = bytes(2**20)
            for _ in range(96):
                fh.write(zeros)


def _patched(path, offset: int, value: bytes):
    """A valid .npz with a field of every central-directory entry overwritten (found by bench_fuzz.py)."""
    _npz(path, _good_members())
    data = bytearray(path.read_bytes())
    at = data.find(b"PK\x01\x02")
    while at >= 0:
        data[at + offset:at + offset + len(value)] = value
        at = data.find(b"PK\x01\x02", at + 4)
    path.write_bytes(bytes(data))


NPZ_CASES = {
    "unknown compression method": (lambda p: _patched(p, 10, b"\x63\x00"), "not an accelrig .npz"),
    "encrypted member": (lambda p: _patched(p, 8, b"\x01\x00"), "not an accelrig .npz"),
    "a .npy named .npz": (lambda p: p.write_bytes(_npy_bytes(np.zeros((10, 3)))), "a single .npy array"),
    "not a zip": (lambda p: p.write_bytes(b"PK\x03\x04 truncated"), "not a zip archive"),
    "truncated": (lambda p: (_npz(p, _good_members()), p.write_bytes(p.read_bytes()[:900])), "not an accelrig .npz"),
    "declares 10^11 samples": (lambda p: _npz(p, {**_good_members(), "acc": _declaring((10**11, 3))}),
                               "declares shape"),
    "complex": (lambda p: _npz(p, {**_good_members(), "acc": _npy_bytes(np.ones((400, 3)) * 1j)}), "complex"),
    "objects": (lambda p: _npz(p, {**_good_members(), "acc": _npy_bytes(np.array([None] * 3, dtype=object))}),
                "holds object"),
    "NaN": (lambda p: _npz(p, {**_good_members(), "acc": _npy_bytes(np.vstack([np.tile([0, 0, 9.81], (9, 1)),
                                                                                [[np.nan, 0, 9.81]]]))}),
            "array acc holds a NaN or infinite value at row 9"),
    "no meta": (lambda p: _npz(p, {k: v for k, v in _good_members().items() if k != "meta_json"}), "meta_json"),
    "meta a number": (lambda p: _npz(p, {**_good_members(), "meta_json": _npy_bytes(np.arange(3.0))}),
                      "meta_json is not a string"),
    "meta typed wrong": (lambda p: _npz(p, {**_good_members(), "meta_json": _npy_bytes(np.array('{"gaps": 5}'))}),
                         "metadata gaps"),
    "acc of two axes": (lambda p: _npz(p, {**_good_members(), "acc": _npy_bytes(np.zeros((400, 2)))}),
                        "three acceleration axes"),
    "t too short": (lambda p: _npz(p, {**_good_members(), "t": _npy_bytes(np.arange(3.0))}), "one timestamp"),
    "zip bomb": (_bomb, "declares .* bytes uncompressed"),
}


@pytest.mark.parametrize("case", sorted(NPZ_CASES))
def test_hostile_npz_is_refused(case, guarded, tmp_path, monkeypatch):
    make, cause = NPZ_CASES[case]
    if case == "zip bomb":
        monkeypatch.setattr(recording, "MAX_VALUES", 1 << 20)   # 8 MiB: the 96 MiB bomb is 12x over
    path = tmp_path / "rec.npz"
    make(path)
    before = snapshot(tmp_path)
    assert_refused(guarded("calibrate", "static", path, "-o", tmp_path / "p.yaml", memory_mb=300), cause)
    assert snapshot(tmp_path) == before


def test_replay_of_a_nan_recording_is_refused_not_zeroed(guarded, tmp_path):
    path = tmp_path / "nan.npz"
    NPZ_CASES["NaN"][0](path)
    assert_refused(guarded("record", f"replay://{path}?pace=fast", "-o", tmp_path / "out.csv"), "NaN")
    assert not (tmp_path / "out.csv").exists()


def test_profile_apply_never_writes_nan(guarded, tmp_path):
    """The round trip a NaN used to survive: CSV in, .npz out through profile apply."""
    from hostile.support import EXAMPLE_PROFILE

    path = tmp_path / "raw.csv"
    path.write_text(_csv({"identity": "sim-random-11"}, rows=GOOD_ROWS + "2.1,nan,0,9.8\n"))
    assert_refused(guarded("profile", "apply", EXAMPLE_PROFILE, path, "-o", tmp_path / "out.npz"), "NaN")
    assert not (tmp_path / "out.npz").exists()


def test_a_written_recording_reads_back_exactly(tmp_path):
    rec = Recording(np.arange(50) / 200.0, np.tile([0.1, -0.2, 9.8], (50, 1)), "m/s^2",
                    {"theta": np.linspace(0, 1, 50)}, {"gaps": [{"index": 3, "missing": 2, "cause": "link"}]})
    for name, write in (("r.csv", write_csv), ("r.npz", save_native)):
        write(rec, tmp_path / name)
        back = load_recording(tmp_path / name)
        np.testing.assert_allclose(back.acc, rec.acc)
        assert back.meta["gaps"] == rec.meta["gaps"]
