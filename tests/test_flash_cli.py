"""Flashing firmware devices (serial, BLE) and the `accelrig flash` command."""

import io
import sys
import types
from dataclasses import dataclass, field

import numpy as np
import pytest

from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.flash import check_profile_for_device, profile_mismatches
from accelrig.cli import main
from accelrig.errors import DeviceError, ProfileError
from accelrig.procedures.result import Correction

URL = "serial-sim://still?seed=1&pace=fast"
SIM_DEVICE = {"driver": "serial-sim", "chip": "sim-mpu9250", "identity": "SIM-still-1", "range_g": 4.0}


@dataclass
class ProfileShape:
    """The attributes of accelrig.profiles.Profile that flashing uses (BRIEF contract)."""

    correction: Correction
    device: dict
    data: dict = field(default_factory=dict)
    units: str = "m/s^2"


def make_profile(device=None, seed=0):
    rng = np.random.default_rng(seed)
    corr = Correction(np.eye(3) + rng.normal(0, 0.01, (3, 3)), rng.normal(0, 0.1, 3), np.diag(rng.uniform(1e-8, 1e-6, 12)))
    dev = dict(SIM_DEVICE if device is None else device)
    return ProfileShape(corr, dev, {"schema_version": 1, "device": dev, "seed": seed})


@pytest.mark.parametrize("scheme", ["serial-sim", "ble-sim"])
def test_plan_write_read_back_and_plan_again(scheme):
    profile = make_profile()
    with driver_for(f"{scheme}://still?seed=1&pace=fast") as driver:
        plan = driver.plan_flash(profile)
        assert all(w.current is None for w in plan.writes)
        assert "holds no calibration record yet" in " ".join(plan.notes)
        assert driver.firmware.record is None  # planning writes nothing
        report = driver.flash(plan)
        assert report.verified and report.readback
        again = driver.plan_flash(profile)
        row_x = again.writes[0]
        assert row_x.current == plan.writes[0].new  # the device now holds what was written
    stored = np.array([float(v) for v in row_x.current.strip("[]").split(",")])
    np.testing.assert_allclose(stored, profile.correction.matrix[0], rtol=1e-7)
    assert plan.residual["float32 rounding of bias, m/s^2 (max abs)"] < 1e-7


def test_corrupted_store_is_caught_by_read_back():
    with driver_for("serial-sim://still?seed=1&pace=fast&cal_fault=corrupt") as driver:
        report = driver.flash(driver.plan_flash(make_profile()))
    assert not report.verified
    assert any("differs from what was written in 1 byte" in n for n in report.notes)
    assert any("fails its CRC" in n for n in report.notes)


def test_refused_store_is_an_error():
    with driver_for("serial-sim://still?seed=1&pace=fast&cal_fault=refuse") as driver:
        with pytest.raises(DeviceError, match="refused CAL_WRITE: storage error"):
            driver.flash(driver.plan_flash(make_profile()))


def test_profile_for_another_device_is_refused_unless_forced():
    with driver_for("serial-sim://still?seed=1&pace=fast") as driver:
        info = driver.info
    assert profile_mismatches(make_profile(), info) == ([], [])
    for key, value, label in [("chip", "icm20948", "chip"), ("range_g", 16, "range"), ("identity", "SIM-still-2", "device identity")]:
        other = make_profile({**SIM_DEVICE, key: value})
        with pytest.raises(ProfileError, match=f"made for another device: {label}"):
            check_profile_for_device(other, info)
        notes = check_profile_for_device(other, info, force=True)
        assert notes[0].startswith(f"FORCED despite mismatch: {label}")
    bare = make_profile({})
    assert any("chip not checked" in n for n in check_profile_for_device(bare, info))


# ---------------------------------------------------------------- the CLI


@pytest.fixture
def profile_file(tmp_path, monkeypatch):
    """A saved profile of serial-sim://still?seed=1, loaded by the CLI through accelrig.profiles.

    Until the profiles module is on this branch the loader is a stand-in that
    keeps the contract (load_profile(path) -> object with correction/device/data).
    """
    profile = make_profile()
    path = tmp_path / "p.yaml"
    try:
        from accelrig.profiles import profile_from_result, save_profile
    except ImportError:
        stand_in = types.ModuleType("accelrig.profiles")
        stand_in.load_profile = lambda p: profile
        monkeypatch.setitem(sys.modules, "accelrig.profiles", stand_in)
        path.write_text("stand-in\n")
        return path
    from accelrig.acquisition.recorder import record
    from accelrig.procedures.result import CalibrationResult

    with driver_for(URL) as driver:
        rec = record(driver, seconds=0.5)
    result = CalibrationResult("static_faces", "test", "C (raw - b)", profile.correction, {},
                               quality={"residual_rms": 0.03})
    save_profile(profile_from_result(result, rec), path)
    return path


class TtyInput(io.StringIO):
    def isatty(self):
        return True


def test_cli_dry_run_shows_the_plan_and_writes_nothing(profile_file, capsys):
    assert main(["flash", str(profile_file), "--device", URL, "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "Flash plan for serial-sim://still" in out and "record: matrix row x" in out
    assert "(none)" in out and "float32 rounding" in out
    assert "dry run: nothing written" in out and "VERIFIED" not in out


def test_cli_without_terminal_needs_yes(profile_file, capsys, monkeypatch):
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))
    code = main(["flash", str(profile_file), "--device", URL])
    err = capsys.readouterr().err
    assert code == DeviceError.exit_code
    assert "standard input is not a terminal" in err and "pass --yes" in err and err.count("\n") == 1


def test_cli_asks_on_a_terminal(profile_file, capsys, monkeypatch):
    monkeypatch.setattr(sys, "stdin", TtyInput("n\n"))
    assert main(["flash", str(profile_file), "--device", URL]) == 1
    assert "write? [y/N] nothing written" in capsys.readouterr().out
    monkeypatch.setattr(sys, "stdin", TtyInput("y\n"))
    assert main(["flash", str(profile_file), "--device", URL]) == 0
    out = capsys.readouterr().out
    assert "VERIFIED: serial-sim://still" in out and "record: CRC-16" in out


def test_cli_yes_and_failed_verification(profile_file, capsys):
    assert main(["flash", str(profile_file), "--device", URL, "--yes"]) == 0
    assert "VERIFIED" in capsys.readouterr().out
    code = main(["flash", str(profile_file), "--device", URL + "&cal_fault=corrupt", "--yes"])
    captured = capsys.readouterr()
    assert code == DeviceError.exit_code
    assert "NOT VERIFIED" in captured.out and "did not verify" in captured.err


def test_cli_refuses_mismatch_and_devices_without_store(profile_file, capsys):
    code = main(["flash", str(profile_file), "--device", "serial-sim://still?seed=2&pace=fast", "--yes"])
    assert code == ProfileError.exit_code
    assert "device identity: profile 'SIM-still-1', device 'SIM-still-2'" in capsys.readouterr().err
    assert main(["flash", str(profile_file), "--device", "serial-sim://still?seed=2&pace=fast", "--yes", "--force"]) == 0
    assert "FORCED despite mismatch" in capsys.readouterr().out
    code = main(["flash", str(profile_file), "--device", "sim://still", "--force", "--dry-run"])
    assert code == DeviceError.exit_code
    assert "sim:// devices cannot store a calibration" in capsys.readouterr().err
