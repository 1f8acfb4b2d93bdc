"""Flashing firmware devices (serial, BLE) and the `accelrig flash` command."""

import io
import sys
from pathlib import Path

import numpy as np
import pytest

from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.recorder import record
from accelrig.cli import main
from accelrig.errors import DeviceError, ProfileError
from accelrig.profiles import profile_from_result, save_profile
from accelrig.profiles.flash import plan_flash
from accelrig.result import CalibrationResult, Correction

URL = "serial-sim://still?seed=1&pace=fast"
SIM_DEVICE = {"driver": "serial-sim", "chip": "sim-mpu9250", "identity": "SIM-1", "range_g": 4.0}


def make_profile(device=None, seed=0):
    """A real accelrig.profiles.Profile with a random small correction, for the given device block."""
    rng = np.random.default_rng(seed)
    corr = Correction(np.eye(3) + rng.normal(0, 0.01, (3, 3)), rng.normal(0, 0.1, 3), np.diag(rng.uniform(1e-8, 1e-6, 12)))
    result = CalibrationResult("static_faces", "test", "C (raw - b)", corr, {}, quality={"residual_rms": 0.03})
    return profile_from_result(result, None, device=dict(SIM_DEVICE if device is None else device))


@pytest.mark.parametrize("scheme", ["serial-sim", "ble-sim"])
def test_plan_write_read_back_and_plan_again(scheme):
    profile = make_profile()
    with driver_for(f"{scheme}://still?seed=1&pace=fast") as driver:
        plan = plan_flash(driver, profile)
        assert all(w.current is None for w in plan.writes)
        assert "holds no calibration record yet" in " ".join(plan.notes)
        assert driver.firmware.record is None  # planning writes nothing
        report = driver.flash(plan)
        assert report.verified and report.readback
        again = plan_flash(driver, profile)
        row_x = again.writes[0]
        assert row_x.current == plan.writes[0].new  # the device now holds what was written
    stored = np.array([float(v) for v in row_x.current.strip("[]").split(",")])
    np.testing.assert_allclose(stored, profile.correction.matrix[0], rtol=1e-7)
    assert plan.residual["float32 rounding of bias, m/s^2 (max abs)"] < 1e-7


def test_corrupted_store_is_caught_by_read_back():
    with driver_for("serial-sim://still?seed=1&pace=fast&cal_fault=corrupt") as driver:
        report = driver.flash(plan_flash(driver, make_profile()))
    assert not report.verified
    assert any("differs from what was written in 1 byte" in n for n in report.notes)
    assert any("fails its CRC" in n for n in report.notes)


def test_refused_store_is_an_error():
    with driver_for("serial-sim://still?seed=1&pace=fast&cal_fault=refuse") as driver:
        with pytest.raises(DeviceError, match="refused CAL_WRITE: storage error"):
            driver.flash(plan_flash(driver, make_profile()))


def test_profile_for_another_device_is_refused_unless_forced():
    with driver_for("serial-sim://still?seed=1&pace=fast") as driver:
        plan = plan_flash(driver, make_profile())
        assert not any("forced" in n for n in plan.notes)
        for key, value, label in [("chip", "icm20948", "chip"), ("range_g", 16, "range"),
                                  ("identity", "SIM-2", "device")]:
            other = make_profile({**SIM_DEVICE, key: value})
            with pytest.raises(ProfileError, match=label):
                plan_flash(driver, other)
            notes = plan_flash(driver, other, force=True).notes
            assert any(n.startswith("forced") and label in n for n in notes)
        bare = make_profile({})
        assert any("cannot check the profile belongs to this device" in n for n in plan_flash(driver, bare).notes)


# ---------------------------------------------------------------- the CLI


@pytest.fixture
def profile_file(tmp_path):
    """A saved profile of serial-sim://still?seed=1, made from a recording of that device."""
    with driver_for(URL) as driver:
        rec = record(driver, seconds=0.5)
    path = tmp_path / "p.yaml"
    result = CalibrationResult("static_faces", "test", "C (raw - b)", make_profile().correction, {},
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
    assert "is for device 'SIM-1', not 'SIM-2'" in capsys.readouterr().err
    assert main(["flash", str(profile_file), "--device", "serial-sim://still?seed=2&pace=fast", "--yes", "--force"]) == 0
    assert "forced: " in capsys.readouterr().out
    code = main(["flash", str(profile_file), "--device", "sim://still", "--force", "--dry-run"])
    assert code == DeviceError.exit_code
    assert "sim:// devices cannot store a calibration" in capsys.readouterr().err


@pytest.mark.parametrize("scheme", ["serial-sim", "ble-sim"])
def test_a_simulated_device_keeps_its_flashed_record_between_opens(profile_file, capsys, scheme, tmp_path,
                                                                    monkeypatch):
    """flash ... VERIFIED, then the next open (another process in life) shows that record, as a board's flash
    keeps it: the record lives in the accelrig home, one file per device identity, never in the checkout."""
    import os

    monkeypatch.chdir(tmp_path)
    url = f"{scheme}://still?seed=1&pace=fast"
    assert main(["flash", str(profile_file), "--device", url, "--yes"]) == 0
    assert "VERIFIED" in capsys.readouterr().out
    assert main(["flash", str(profile_file), "--device", url, "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "holds no calibration record yet" not in out and "(none)" not in out, out
    stored = list((Path(os.environ["ACCELRIG_HOME"]) / "sim-devices").glob("SIM-1.cal"))
    assert len(stored) == 1 and not list(tmp_path.rglob("*.cal"))
    # a record the store damaged is shown as such and flashed over, not a dead end
    assert main(["flash", str(profile_file), "--device", url + "&cal_fault=corrupt", "--yes"]) != 0
    capsys.readouterr()
    assert main(["flash", str(profile_file), "--device", url, "--yes"]) == 0
    out = capsys.readouterr().out
    assert "cannot be used (the calibration record stored on the device fails its CRC" in out and "VERIFIED" in out
