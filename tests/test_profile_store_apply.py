"""Profile store, apply (recordings and ring-buffer readers), and the profile CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from datetime import UTC, datetime

import numpy as np
import pytest
import yaml

from accelrig.acquisition.block import Block
from accelrig.acquisition.ringbuffer import RingBuffer
from accelrig.errors import ProfileError
from accelrig.profiles import load_profile, profile_from_result, save_profile
from accelrig.profiles.apply import CalibratedReader, apply_profile, sample_uncertainty
from accelrig.profiles.store import ProfileStore, default_store_dir, device_key
from accelrig.recording import Recording, read_csv, write_csv
from accelrig.result import CalibrationResult, Correction, format_value
from accelrig.sim.device import simulate
from accelrig.sim.rigs.still import StillRig
from accelrig.sim.sensor import SensorModel, SimClock
from tests.test_profile_io import MALFORMED, _edit, make_result


def run_cli(*args):
    """A real process: proves the one-line error and exit status end to end (slow: use sparingly)."""
    return subprocess.run([sys.executable, "-m", "accelrig", *args], capture_output=True, text=True, timeout=120)


def truth_profile(sensor: SensorModel, identity="dev-1", created=None, cov_scale=1e-4):
    """A profile holding the sensor's true correction (and a made-up but valid covariance)."""
    corr = sensor.correction()
    rng = np.random.default_rng(2)
    a = cov_scale * rng.standard_normal((12, 12))
    res = CalibrationResult("static_faces", "truth", "C (raw - b)", Correction(corr.matrix, corr.bias, a @ a.T), {})
    dev = {"identity": identity, "range_g": sensor.range_g, "scale": sensor.scale, "driver": "sim", "chip": "sim"}
    return profile_from_result(res, device=dev, created=created)


def raw_csv(tmp_path, seconds=0.5):
    """A still recording of device 'dev-1' (a random +-2 g sensor, no noise) as raw.csv: (sensor, rec, path)."""
    sensor = SensorModel.random(np.random.default_rng(11), noise_density=0.0)
    rec = simulate(StillRig(), sensor, SimClock(), seconds=seconds, seed=1)
    rec.meta["identity"] = "dev-1"
    raw = tmp_path / "raw.csv"
    write_csv(rec, raw)
    return sensor, rec, raw


def test_sample_covariances_equal_the_per_sample_definition():
    rng = np.random.default_rng(3)
    a = rng.standard_normal((12, 12)) * 1e-3
    corr = Correction(np.eye(3) + 0.02 * rng.standard_normal((3, 3)), rng.standard_normal(3), a @ a.T)
    raw = rng.standard_normal((50, 3)) * 9.8
    fast = corr.sample_covariances(raw)
    for k in range(raw.shape[0]):
        # the definition: Jacobian of y = C (x - b) with respect to [C.ravel(), b]
        d = raw[k] - corr.bias
        jac = np.zeros((3, 12))
        for i in range(3):
            jac[i, 3 * i:3 * i + 3] = d
        jac[:, 9:] = -corr.matrix
        np.testing.assert_allclose(fast[k], jac @ corr.covariance @ jac.T, rtol=1e-10, atol=1e-18)
    np.testing.assert_allclose(sample_uncertainty(corr, raw, chunk=7),
                               np.sqrt(np.diagonal(fast, axis1=1, axis2=2)), rtol=1e-12)


def test_sample_uncertainty_matches_monte_carlo():
    rng = np.random.default_rng(4)
    a = rng.standard_normal((12, 12)) * 2e-3
    cov = a @ a.T
    corr = Correction(np.eye(3) * 1.01, [0.1, -0.2, 0.3], cov)
    x = np.array([1.0, -2.0, 9.8])
    draws = rng.multivariate_normal(np.concatenate([corr.matrix.ravel(), corr.bias]), cov, 20000)
    ys = np.array([d[:9].reshape(3, 3) @ (x - d[9:]) for d in draws])
    np.testing.assert_allclose(np.std(ys, axis=0), sample_uncertainty(corr, x[None])[0], rtol=0.03)


def test_apply_recovers_true_force(tmp_path):
    sensor = SensorModel.random(np.random.default_rng(8), noise_density=0.0)
    rec = simulate(StillRig(up="-y"), sensor, SimClock(), seconds=1.0, seed=1)
    rec.meta["identity"] = "dev-1"
    out, warnings = apply_profile(truth_profile(sensor), rec, uncertainty=True)
    assert warnings == []
    np.testing.assert_allclose(out.acc.mean(axis=0), [0, -9.80665, 0], atol=2 * sensor.scale)
    assert set(out.channels) >= {"u_ax", "u_ay", "u_az"} and np.all(out.channels["u_ay"] > 0)
    assert out.meta["calibrated_with"]["identity"] == "dev-1"
    with pytest.raises(ProfileError, match="already"):
        apply_profile(truth_profile(sensor), out)


def test_apply_in_counts_uses_the_scale(tmp_path):
    sensor = SensorModel.random(np.random.default_rng(9), noise_density=0.0)
    rec = simulate(StillRig(), sensor, SimClock(), seconds=0.5, seed=1, units="counts")
    rec.meta["identity"] = "dev-1"
    out, _ = apply_profile(truth_profile(sensor), rec)
    np.testing.assert_allclose(out.acc.mean(axis=0), [0, 0, 9.80665], atol=2 * sensor.scale)


@pytest.mark.parametrize(
    "meta,units,message",
    [
        ({"identity": "dev-2"}, "m/s^2", "is for device 'dev-1', not 'dev-2'"),
        ({"identity": "dev-1", "range_g": 4.0}, "m/s^2", "is for the +-2 g range but the data were taken at +-4 g"),
        ({"identity": "dev-1"}, "g", "the data are in g but"),
    ],
)
def test_apply_refuses_another_device_range_or_unit_unless_forced(meta, units, message):
    sensor = SensorModel(noise_density=0.0)
    rec = simulate(StillRig(), sensor, SimClock(), seconds=0.2, seed=1)
    acc = rec.acc / 9.80665 if units == "g" else rec.acc
    rec = Recording(rec.t, acc, units, {}, dict(rec.meta, **meta))
    profile = truth_profile(sensor)
    with pytest.raises(ProfileError, match=message.replace("+", r"\+")):
        apply_profile(profile, rec)
    out, warnings = apply_profile(profile, rec, force=True)
    assert any(w.startswith("forced: ") for w in warnings)
    if units == "g":
        np.testing.assert_allclose(out.acc.mean(axis=0), [0, 0, 9.80665], atol=2e-3)


def test_calibrated_reader_in_the_acquisition_path():
    sensor = SensorModel.random(np.random.default_rng(10), noise_density=0.0)
    rec = simulate(StillRig(up="+x"), sensor, SimClock(), seconds=1.0, seed=1, units="counts")
    buf = RingBuffer(1024, sensor.scale)
    reader = CalibratedReader(buf.reader(), truth_profile(sensor), device={"identity": "dev-1", "range_g": 2.0},
                              uncertainty=True)
    counts = rec.acc.astype(np.int16)
    buf.write(Block(seq=0, counter=0, host_time=0.0, counts=counts[:100], scale=sensor.scale, t=rec.t[:100]))
    got = reader.read()
    assert got.n == 100 and got.uncertainty.shape == (100, 3)
    np.testing.assert_allclose(got.acc.mean(axis=0), [9.80665, 0, 0], atol=2 * sensor.scale)
    with pytest.raises(ProfileError, match="is for the \\+-2 g range but the data were taken at \\+-8 g"):
        CalibratedReader(buf.reader(), truth_profile(sensor), device={"identity": "dev-1", "range_g": 8.0})
    other = RingBuffer(16, sensor.scale * 4)
    with pytest.raises(ProfileError, match="m/s\\^2 per count"):
        CalibratedReader(other.reader(), truth_profile(sensor))


# ------------------------------------------------------------------ store


def test_store_location_follows_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("ACCELRIG_HOME", str(tmp_path / "home"))
    assert default_store_dir() == tmp_path / "home" / "profiles"
    monkeypatch.delenv("ACCELRIG_HOME")
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert default_store_dir() == tmp_path / "xdg" / "accelrig" / "profiles"


def test_device_key_is_safe_and_distinct():
    a, b = device_key("AA:BB:CC:DD:EE:FF"), device_key("AA_BB_CC_DD_EE_FF")
    assert a != b and "/" not in device_key("../../etc/passwd") and ":" not in a
    assert not device_key("../x").startswith(".")


def test_store_choose_latest_closest_and_old(tmp_path):
    store = ProfileStore(tmp_path / "store")
    sensor = SensorModel()
    dates = ["2026-01-10T00:00:00Z", "2026-06-01T00:00:00Z", "2026-11-01T00:00:00Z"]
    paths = [store.add(truth_profile(sensor, created=d)) for d in dates]
    store.add(truth_profile(sensor, identity="dev-2", created=dates[0]))
    assert len(store.entries("dev-1")) == 3 and store.identities() == ["dev-1", "dev-2"]
    now = datetime(2026, 11, 22, tzinfo=UTC)
    latest = store.choose("dev-1", now=now)
    assert latest.stored.path == paths[2] and latest.warnings == []
    closest = store.choose("dev-1", date="2026-05-01")
    assert closest.stored.path == paths[1]
    old = store.choose("dev-1", max_age_days=10, now=now)
    assert "days older than now" in old.warnings[0]
    with pytest.raises(ProfileError, match="no stored profile for device 'dev-9'.*known devices: dev-1, dev-2"):
        store.choose("dev-9")
    # the same creation time twice does not overwrite, and the one added later counts as newer
    again = store.add(truth_profile(sensor, created=dates[2], identity="dev-1"))
    assert again != paths[2] and again.exists()
    assert store.choose("dev-1", now=now).stored.path == again
    with pytest.raises(ProfileError, match="does not name its device"):
        store.add(profile_from_result(make_result()))


# ------------------------------------------------------------------ CLI


def test_cli_apply_list_show_diff_validate(tmp_path, cli):
    sensor, rec, raw = raw_csv(tmp_path)
    prof = tmp_path / "p.yaml"
    save_profile(truth_profile(sensor), prof)
    out = tmp_path / "cal.csv"
    r = cli("profile", "apply", str(prof), str(raw), "-o", str(out), "--uncertainty")
    assert r.returncode == 0, r.stderr
    cal = read_csv(out)
    np.testing.assert_allclose(cal.acc.mean(axis=0), [0, 0, 9.80665], atol=2e-3)
    assert "u_az" in cal.channels

    store = tmp_path / "store"
    r = cli("profile", "add", str(prof), "--store", str(store))
    assert r.returncode == 0, r.stderr
    r = cli("profile", "list", "--store", str(store))
    assert "dev-1" in r.stdout and "static_faces" in r.stdout
    assert max(len(line) for line in r.stdout.splitlines()) <= 80, r.stdout   # the file stacks under the table
    r = cli("profile", "show", "dev-1", "--store", str(store))
    assert r.returncode == 0 and "calibrated = C @ (raw - b)" in r.stdout
    out2 = tmp_path / "cal2.csv"
    r = cli("profile", "apply", "auto", str(raw), "-o", str(out2), "--store", str(store))
    assert r.returncode == 0, r.stderr
    np.testing.assert_array_equal(read_csv(out2).acc, cal.acc)

    other = tmp_path / "q.yaml"
    p2 = load_profile(prof)
    p2.data["calibration"]["correction"]["bias"][0] += 0.5
    save_profile(p2, other)
    r = cli("profile", "diff", str(prof), str(other))
    assert r.returncode == 1 and "calibration.correction.bias" in r.stdout and "E_n" in r.stdout
    assert cli("profile", "diff", str(prof), str(prof)).returncode == 0

    # another device's recording: refused in one line, nothing written
    rec.meta["identity"] = "dev-2"
    write_csv(rec, raw)
    out3 = tmp_path / "cal3.csv"
    r = run_cli("profile", "apply", str(prof), str(raw), "-o", str(out3))
    assert r.returncode != 0 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
    assert "'dev-1', not 'dev-2'" in r.stderr and not out3.exists()
    r = cli("profile", "apply", str(prof), str(raw), "-o", str(out3), "--force")
    assert r.returncode == 0 and "warning: forced" in r.stderr


def test_cli_validate_malformed_files_one_line_each(tmp_path, cli):
    good = tmp_path / "good.yaml"
    save_profile(profile_from_result(make_result()), good)
    text = good.read_text()
    bad_files = {
        "matrix.yaml": (text.replace("matrix:\n    - [", "matrix:\n    - [7, ", 1), "calibration.correction.matrix: expected 3x3 numbers"),
        "tag.yaml": (text.replace("warnings: [", "warnings: [!!python/name:os.system , ", 1), "could not determine a constructor"),
        "unknown.yaml": (text + "colour: blue\n", "colour: unknown key"),
        "missing.yaml": (text.replace("units: m/s^2\n", ""), "units: missing (required field)"),
        "type.yaml": (text.replace("  g: 9.80665", "  g: heavy"), "calibration.g: expected a number, got the string 'heavy'"),
        "version.yaml": (text.replace("schema_version: 1", "schema_version: 3"), "schema_version: 3 is newer"),
    }
    for name, (content, message) in bad_files.items():
        path = tmp_path / name
        path.write_text(content)
        r = (run_cli if name == "tag.yaml" else cli)("profile", "validate", str(path))
        assert r.returncode == 6, (name, r.stderr)
        assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
        assert message in r.stderr, (name, r.stderr)
    r = cli("profile", "validate", str(good), *(str(tmp_path / n) for n in bad_files))
    assert r.returncode == 6 and r.stderr.count("\n") == len(bad_files) and "good.yaml: ok" in r.stdout


@pytest.mark.parametrize("dotted,value,message", MALFORMED, ids=[f"{m[0]}={m[1]!r}"[:50] for m in MALFORMED])
def test_cli_validate_refuses_each_malformed_profile(tmp_path, cli, dotted, value, message):
    """Every malformed profile of the load tests, through the command: exit 6, one line naming the field."""
    data = _edit(json.loads(json.dumps(profile_from_result(make_result()).data)), dotted, value)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    r = cli("profile", "validate", path)
    assert r.returncode == 6 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and message in r.stderr, r.stderr


def test_profile_show_gives_angles_in_degrees_as_every_other_view(cli):
    """The profile keeps radians; `profile show`, like calibrate, the TUI and the certificate, shows degrees."""
    from pathlib import Path

    example = Path(__file__).resolve().parent.parent / "profiles" / "example-static_faces-vp.yaml"
    r = cli("profile", "show", str(example))
    assert r.returncode == 0, r.stderr
    angle = next(line for line in r.stdout.splitlines() if line.strip().startswith("angle_x"))
    stored = load_profile(example).data["calibration"]["parameters"]["angle_x"]
    value, u = format_value(np.degrees(stored["value"]), np.degrees(stored["uncertainty"]))   # rounded with u
    assert angle.endswith(" deg") and f"{value} +- {u}" in angle


def test_profile_show_gives_g_as_every_face_does(tmp_path, cli):
    """A local g from the latitude (9.807394654606906) is shown to 0.01 mm/s^2 with its u, as the calibration's
    text and the certificate give it, not with every digit of the float."""
    from pathlib import Path

    import yaml

    example = Path(__file__).resolve().parent.parent / "profiles" / "example-static_faces-vp.yaml"
    data = yaml.safe_load(example.read_text())
    data["calibration"]["g"] = data["calibration"]["settings"]["g"] = 9.807394654606906
    data["calibration"]["settings"]["g_u"] = 1.2345e-4
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(data))
    r = cli("profile", "show", str(tmp_path / "p.yaml"))
    assert r.returncode == 0, r.stderr
    assert "g = 9.80739 +- 0.00012 m/s^2" in r.stdout and "9.807394654606906" not in r.stdout, r.stdout


def test_profile_show_fits_80_columns_and_reads_every_sentence_whole(cli):
    """What u holds and the warnings are sentences: shown whole, wrapped under their label (they were cut at
    80 characters with '...'); numbers in lists at 4 digits; every line within 80 columns."""
    from pathlib import Path

    for name in ("example-static_faces-vp.yaml", "example-wheel-joint.yaml"):
        example = Path(__file__).resolve().parent.parent / "profiles" / name
        r = cli("profile", "show", str(example))
        assert r.returncode == 0, r.stderr
        assert max(len(line) for line in r.stdout.splitlines()) <= 80, r.stdout
        data = load_profile(example).data
        shown = " ".join(r.stdout.split())
        said = data["quality"].get("uncertainty_source") or data["quality"]["uncertainty"]   # the wheel says "uncertainty"
        for sentence in [said, *data["warnings"]]:
            assert " ".join(sentence.split()) in shown, sentence


def test_apply_from_the_store_picks_the_newest_profile_that_applies_and_says_why(tmp_path, cli):
    sensor, rec, raw = raw_csv(tmp_path)
    store = ProfileStore(tmp_path / "store")
    static = store.add(truth_profile(sensor, created="2026-11-01T00:00:00Z"))
    wheel = truth_profile(sensor, created="2026-11-20T00:00:00Z")
    wheel.data["device"]["range_g"] = 4.0          # the wheel's profile: another range, newer
    wheel.data["device"]["scale"] = 2 * sensor.scale
    wheel = store.add(wheel)
    for spec in ("auto", "dev-1"):
        out = tmp_path / f"cal-{spec}.csv"
        r = cli("profile", "apply", spec, str(raw), "-o", str(out), "--store", str(store.root))
        assert r.returncode == 0, r.stderr    # was: refused with the +-4 g profile, the +-2 g one in the store
        np.testing.assert_allclose(read_csv(out).acc.mean(axis=0), [0, 0, 9.80665], atol=2e-3)
        assert f"profile {static.name} (static_faces, ±2 g" in r.stderr and "that applies to the data" in r.stderr
        assert f"passed over {wheel.name}" in r.stderr and "+-4 g range but the data were taken at +-2 g" in r.stderr
    # none applies: refused, and the CLI's hint says only what the CLI can do
    static.unlink()
    r = cli("profile", "apply", "dev-1", str(raw), "-o", str(tmp_path / "none.csv"), "--store", str(store.root))
    assert r.returncode != 0 and "+-4 g range" in r.stderr and "--force" in r.stderr and "TUI" not in r.stderr


def test_a_profile_and_data_that_both_leave_the_device_unnamed_are_said_in_grammar():
    sensor = SensorModel(noise_density=0.0)
    rec = simulate(StillRig(), sensor, SimClock(), seconds=0.2, seed=1)
    rec = Recording(rec.t, rec.acc, "m/s^2", {}, dict(rec.meta, identity=None))
    profile = truth_profile(sensor)
    profile.data["device"]["identity"] = None
    warnings = apply_profile(profile, rec)[1]
    assert "neither the profile nor the data name the device" in " ".join(warnings)


def test_a_damaged_store_file_is_skipped_with_a_warning_and_the_older_profile_chosen(tmp_path, cli):
    """One half-copied file must not stop every device: it is skipped, named and listed as broken; its device
    falls back to its newest profile that loads, and a device left with none is told to repair, not recalibrate."""
    sensor = SensorModel()
    store = ProfileStore(tmp_path / "store")
    older = store.add(truth_profile(sensor, created="2026-11-01T00:00:00Z"))
    other = store.add(truth_profile(sensor, identity="dev-2", created="2026-11-01T00:00:00Z"))
    damaged = older.parent / "20261125T040000Z-static.yaml"
    damaged.write_text(older.read_text()[:200])   # cut off mid-copy: not valid YAML
    assert [s.path for s in store.entries()] == sorted([older, other])
    assert [b.path for b in store.scan()[1]] == [damaged]
    choice = store.choose("dev-1", now=datetime(2026, 11, 26, tzinfo=UTC))
    assert choice.stored.path == older and [b.path for b in choice.skipped] == [damaged]
    # the damaged file is newer than the one used: said first, as an older calibration in use (the reviewer
    # found it said only "skipped a store entry" while an 11-month-old profile calibrated the data)
    assert choice.warnings[0].startswith(f"the newest profile filed for 'dev-1' ({damaged.name}) cannot be read: "
                                         f"an older one is used instead ({older.name}")
    assert str(damaged) in choice.warnings[1] and "repair or remove it" in choice.warnings[1]
    assert store.choose("dev-2").warnings == []   # another device's damaged file is not its concern
    r = cli("profile", "list", "--store", str(store.root))
    assert r.returncode == 0, r.stderr
    assert "dev-1" in r.stdout and "dev-2" in r.stdout
    broken_row = next(line for line in r.stdout.splitlines() if damaged.name in line)
    assert broken_row.startswith("BROKEN")
    assert f"skipped a store entry that cannot be used: {damaged}" in r.stderr and "not valid YAML" in r.stderr
    # the device's only file is damaged: refused, naming it, and the fix is to repair it
    older.unlink()
    with pytest.raises(ProfileError) as err:
        store.choose("dev-1")
    assert str(damaged) in err.value.message and "repair or remove that file" in err.value.hint


def test_apply_from_the_store_names_the_profile_chosen_even_when_it_is_the_only_one(tmp_path, cli):
    """docs/profiles.md: stderr names the profile chosen (it said nothing when no other was passed over)."""
    sensor, rec, raw = raw_csv(tmp_path, seconds=0.2)
    store = ProfileStore(tmp_path / "store")
    only = store.add(truth_profile(sensor, created="2026-11-01T00:00:00Z"))
    for spec in ("auto", "dev-1"):
        r = cli("profile", "apply", spec, str(raw), "-o", str(tmp_path / f"{spec}.csv"), "--store", str(store.root))
        assert r.returncode == 0, r.stderr
        assert f"accelrig: profile {only} (static_faces, ±2 g, 2026-11-01 00:00): the " in r.stderr, r.stderr
        assert "of 1 stored for 'dev-1' that applies to the data" in r.stderr


def test_applying_a_profile_to_a_daemons_calibrated_output_leaves_its_calibrated_copies_out_and_says_so():
    """The daemon's calibrated segments hold raw counts plus cal_x.. and u_x..: applying a profile calibrates the
    counts again; the recorded copies are left out (they duplicated ax and u_ax silently), and the warning says so."""
    sensor = SensorModel.random(np.random.default_rng(11), noise_density=0.0)
    rec = simulate(StillRig(), sensor, SimClock(), seconds=0.2, seed=1)
    profile = truth_profile(sensor, identity=None)
    first, _ = apply_profile(profile, rec, uncertainty=True)
    channels = {"cal_x": first.acc[:, 0], "cal_y": first.acc[:, 1], "cal_z": first.acc[:, 2],
                **{f"u_{a}": first.channels[f"u_a{a}"] for a in "xyz"}}
    reference = {"path": "/store/p.yaml", "identity": profile.identity, "created": profile.data["provenance"]["created"],
                 "procedure": profile.procedure, "method": profile.method}
    daemon_output = Recording(rec.t, rec.acc, rec.units, channels, dict(rec.meta, profile=reference))
    out, warnings = apply_profile(profile, daemon_output, uncertainty=True)
    assert sorted(out.channels) == ["u_ax", "u_ay", "u_az"]
    np.testing.assert_array_equal(out.acc, first.acc)
    said = next(w for w in warnings if "cal_x, cal_y, cal_z, u_x, u_y, u_z" in w)
    assert "left out" in said and "that same profile" in said and "/store/p.yaml" in said
    other = truth_profile(sensor, identity=None, created="2026-12-01T00:00:00Z")
    _, warnings = apply_profile(other, daemon_output)
    assert any("left out" in w and "that same profile" not in w for w in warnings)
