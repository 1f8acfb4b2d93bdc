
import numpy as np
import pytest

from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.recorder import record
from accelrig.errors import DataError, DeviceError
from accelrig.recording import Recording, guess_units, load_recording, read_csv, save_recording, write_csv
from accelrig.sim.device import simulate
from accelrig.sim.rigs.still import StillRig
from accelrig.sim.sensor import SensorModel, SimClock


def sample_recording(n=50):
    rng = np.random.default_rng(1)
    t = np.arange(n) / 100.0
    acc = rng.normal(0, 1, (n, 3)) + [0, 0, 9.81]
    return Recording(t, acc, "m/s^2", {"theta": np.linspace(0, 1, n)}, {"device": "x", "range_g": 2.0})


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_round_trip_keeps_data_channels_and_meta(tmp_path, suffix):
    rec = sample_recording()
    path = tmp_path / f"r{suffix}"
    save_recording(rec, path)
    back = load_recording(path)
    np.testing.assert_allclose(back.t, rec.t, atol=1e-9)
    np.testing.assert_allclose(back.acc, rec.acc, rtol=1e-9)
    np.testing.assert_allclose(back.channels["theta"], rec.channels["theta"], rtol=1e-9)
    assert back.meta["device"] == "x" and back.units == "m/s^2"


def test_csv_without_t_needs_rate(tmp_path):
    p = tmp_path / "a.csv"
    p.write_text("# a comment\nax,ay,az,step\n0,0,9.8,1\n0,0,9.8,1\n")
    with pytest.raises(DataError, match="no 't' column"):
        read_csv(p)
    rec = read_csv(p, rate=100)
    np.testing.assert_allclose(rec.t, [0, 0.01])
    assert list(rec.channels) == ["step"]


@pytest.mark.parametrize(
    "content, message",
    [
        ("", "empty file"),
        ("t,ax,ay,az\n", "no data rows"),
        ("t,ax,ay\n0,1,2\n", "lacks column(s) az"),
        ("0,1,2,3\n", "holds numbers, not column names"),
        ("t,ax,ay,az\n0,1,2,3\n1,2,3\n", ":3: expected 4 values"),
        ("t,ax,ay,az\n0,1,2,3\n1,2,x,3\n", ":3: 'x' is not a number"),
        ("t,ax,ay,az\n1,1,2,3\n0,2,3,3\n", "does not increase"),
        ("t,ax,ay,az,ax\n0,1,2,3,4\n", "appear twice"),
        ("t,ax,ay,az\n0,1,nan,3\n", "NaN or infinite"),
    ],
)
def test_malformed_csv_is_one_clear_error(tmp_path, content, message):
    p = tmp_path / "bad.csv"
    p.write_text(content)
    with pytest.raises(DataError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_csv(p)


def test_binary_and_missing_files(tmp_path):
    p = tmp_path / "b.csv"
    p.write_bytes(b"\xff\xfe\x00\x01")
    with pytest.raises(DataError, match="not a text file"):
        read_csv(p)
    with pytest.raises(DataError, match="no such file"):
        read_csv(tmp_path / "none.csv")
    bad_npz = tmp_path / "c.npz"
    bad_npz.write_bytes(b"not a zip")
    with pytest.raises(DataError, match="not an accelrig .npz"):
        load_recording(bad_npz)


def test_failed_write_leaves_no_partial_file(tmp_path):
    rec = sample_recording()
    rec.meta["bad"] = object()  # not serialisable: the write fails part-way
    with pytest.raises(TypeError):
        write_csv(rec, tmp_path / "out.csv")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_start_and_stop_take_a_utc_time_in_a_file_that_carries_one(tmp_path, suffix):
    """README: every command's --start/--stop takes seconds or a UTC time.  A file written with its UTC time
    origin (record, the daemon) places a UTC time; one without refuses it, saying to give seconds."""
    origin = 1_795_577_290.25   # 2026-11-25T03:28:10.25Z
    rec = sample_recording(400)
    rec.meta.update(time_base="utc", time_origin=origin)
    path = tmp_path / f"utc{suffix}"
    save_recording(rec, path)
    part = load_recording(path, start="2026-11-25T03:28:11Z", stop="2026-11-25T03:28:12.5Z")
    keep = (origin + rec.t >= origin + 0.75 - 1e-9) & (origin + rec.t < origin + 2.25 - 1e-9)
    np.testing.assert_allclose(part.acc, rec.acc[keep], rtol=1e-9)
    np.testing.assert_allclose(load_recording(path, start="0.75", stop="2.25").acc, part.acc)
    # an ISO time without a zone is UTC; the message of an empty range says when the file lies
    assert len(load_recording(path, start="2026-11-25T03:28:11")) == len(rec) - 75
    with pytest.raises(DataError, match=r"spans 3\.990 s from 2026-11-25T03:28:10\.250Z"):
        load_recording(path, start="2026-11-25T04:00:00Z")
    plain = sample_recording(400)
    save_recording(plain, tmp_path / f"plain{suffix}")
    with pytest.raises(DataError, match="carries no absolute time.*seconds from the first sample"):
        load_recording(tmp_path / f"plain{suffix}", start="2026-11-25T03:28:11Z")


def test_guess_units():
    still = np.tile([0.1, 0.2, 9.8], (10, 1))
    assert guess_units(still) == "m/s^2"
    assert guess_units(still / 9.80665) == "g"
    assert guess_units(still / 0.000598) == "counts"


def test_simulation_is_deterministic_and_has_truth():
    rig = StillRig(up="-y", duration=1.0)
    sensor = SensorModel.random(np.random.default_rng(3))
    a = simulate(rig, sensor, SimClock(200, 0.004), seed=5)
    b = simulate(rig, sensor, SimClock(200, 0.004), seed=5)
    np.testing.assert_array_equal(a.acc, b.acc)
    assert len(a) == int(200 * 1.004)
    corr = sensor.correction()
    calibrated = corr.apply(a.acc).mean(axis=0)
    np.testing.assert_allclose(calibrated, [0, -9.80665, 0], atol=0.02)


def test_sim_driver_same_seed_same_data():
    def grab():
        with driver_for("sim://still?seed=4&pace=fast") as d:
            return record(d, samples=500)
    a, b = grab(), grab()
    np.testing.assert_array_equal(a.acc, b.acc)
    assert a.meta["truth"]["sensor"] == b.meta["truth"]["sensor"]


def test_sim_rate_offset_and_gaps_are_reported():
    with driver_for("sim://still?seed=2&pace=fast&rate=1000&rate_error=0.004&drop=0.2&block=50") as d:
        rec = record(d, samples=5000)
    missing = sum(g["missing"] for g in rec.meta["gaps"])
    assert missing > 0 and missing % 50 == 0
    assert abs(rec.meta["device_rate"] - 1004) < 1
    assert rec.meta["delivered_rate"] == pytest.approx(1004 * len(rec) / (len(rec) + missing), rel=1e-3)
    # the timestamps show the holes: total span covers delivered + missing samples
    assert abs(rec.t[-1] * 1004 - (len(rec) - 1 + missing)) < 2


def test_sim_disconnect_is_a_device_error():
    with driver_for("sim://still?pace=fast&disconnect_after=0.5") as d:
        with pytest.raises(DeviceError, match="disconnected"):
            record(d, seconds=2)


def test_url_option_errors():
    for url, msg in [
        ("sim://still?rate=abc", "not a number"),
        ("sim://still?colour=red", "unknown option"),
        ("sim://still?range=3", "not a MEMS range"),
        ("sim://still?pace=slow", "not one of"),
        ("nonsense", "not a device URL"),
    ]:
        with pytest.raises(DeviceError, match=msg):
            driver_for(url).open()


def test_replay_plays_back_the_file(tmp_path):
    with driver_for("sim://still?seed=1&pace=fast") as d:
        original = record(d, samples=300)
    save_recording(original, tmp_path / "r.csv")
    with driver_for(f"replay://{tmp_path / 'r.csv'}?pace=fast&block=64") as d:
        back = record(d)
    assert len(back) == 300
    np.testing.assert_allclose(back.acc, original.acc, atol=1e-6)
    np.testing.assert_allclose(back.t, original.t, atol=1e-8)


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04 truncated zip"])
def test_empty_or_corrupt_npz_is_one_clear_error(tmp_path, content):
    p = tmp_path / "e.npz"
    p.write_bytes(content)
    with pytest.raises(DataError, match="not an accelrig .npz recording"):
        load_recording(p)


def test_declared_units_are_checked_before_any_conversion(tmp_path):
    rec = sample_recording()
    in_g = Recording(rec.t, rec.acc / 9.80665, "m/s^2", {}, {})
    with pytest.raises(DataError, match=r"declared as m/s\^2 but look like g .*use --units g"):
        in_g.to_si()
    counts = Recording(rec.t, rec.acc / 0.000598, "g", {}, {"scale": 0.000598})
    with pytest.raises(DataError, match="use --units counts"):
        counts.to_si()
    np.testing.assert_allclose(Recording(rec.t, rec.acc / 9.80665, "g").to_si().acc, rec.acc)


def test_replay_keeps_the_device_its_gaps_and_flashed_offsets(tmp_path):
    with driver_for("sim://still?seed=2&pace=fast&rate=1000&drop=0.2&block=50") as d:
        original = record(d, samples=3000)
    original.meta["hardware_bias_removed"] = [0.01, -0.02, 0.03]
    save_recording(original, tmp_path / "r.csv")
    with driver_for(f"replay://{tmp_path / 'r.csv'}?pace=fast&block=64") as d:
        assert d.info.identity == original.meta["identity"]
        back = record(d)
    assert back.meta["identity"] == original.meta["identity"]
    assert back.meta["hardware_bias_removed"] == [0.01, -0.02, 0.03]
    assert [(g["index"], g["missing"]) for g in back.meta["gaps"]] == \
        [(g["index"], g["missing"]) for g in original.meta["gaps"]]
    assert len(original.meta["gaps"]) > 0


def test_a_profile_given_as_the_recording_is_named_for_what_it_is(tmp_path):
    from pathlib import Path

    import pytest

    from accelrig.errors import DataError
    from accelrig.recording import load_recording

    profile = Path(__file__).resolve().parents[1] / "profiles" / "example-static_faces-vp.yaml"
    with pytest.raises(DataError, match="a YAML file .*not a recording"):
        load_recording(profile)
