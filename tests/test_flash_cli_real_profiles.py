"""`accelrig flash` end to end with real profiles (accelrig.profiles) and the serial/BLE simulators."""

import numpy as np
import pytest

from accelrig import profiles
from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.recorder import record
from accelrig.cli import main
from accelrig.result import CalibrationResult, Correction, Estimate


def saved_profile(tmp_path, url):
    """Record the device, calibrate it with its own truth (a stand-in result), save the profile."""
    with driver_for(url) as driver:
        rec = record(driver, seconds=1.0)
        truth = driver.firmware.sensor.correction()
    rng = np.random.default_rng(0)
    a = 1e-4 * rng.standard_normal((12, 12))
    result = CalibrationResult(
        procedure="static_faces", method="truth", model="C (raw - b)",
        correction=Correction(truth.matrix, truth.bias, a @ a.T),
        parameters={"offset": Estimate(truth.bias.tolist(), [1e-3] * 3, "m/s^2")},
        quality={"residual_rms": 0.03, "n_samples": len(rec)},
    )
    profile = profiles.profile_from_result(result, rec)
    path = tmp_path / "device.yaml"
    profiles.save_profile(profile, path)
    return path, profile


class Run:
    def __init__(self, code, out, err):
        self.returncode, self.stdout, self.stderr = code, out, err


@pytest.fixture
def flash(capsys):
    """Run `accelrig flash ARGS` in this process (the CLI's main, as the console script does)."""

    def run(*args):
        code = main(["flash", *args])
        captured = capsys.readouterr()
        return Run(code, captured.out, captured.err)

    return run


@pytest.mark.parametrize("scheme", ["serial-sim", "ble-sim"])
def test_flash_a_saved_profile_and_verify(tmp_path, scheme, flash):
    url = f"{scheme}://still?seed=4&pace=fast"
    path, profile = saved_profile(tmp_path, url)
    assert profile.device["identity"] == "SIM-4"
    r = flash(str(path), "--device", url, "--yes")
    assert r.returncode == 0, r.stderr
    assert "VERIFIED" in r.stdout and "record: matrix row x" in r.stdout
    row = f"{profile.correction.matrix[0, 0]:.5f}"[:6]
    assert row in r.stdout


def test_profile_of_another_device_is_refused_unless_forced(tmp_path, flash):
    path, _ = saved_profile(tmp_path, "serial-sim://still?seed=4&pace=fast")
    r = flash(str(path), "--device", "serial-sim://still?seed=5&pace=fast", "--yes")
    assert r.returncode != 0 and "Traceback" not in r.stderr
    assert "is for device 'SIM-4', not 'SIM-5'" in r.stderr
    assert "--force" in r.stderr
    r = flash(str(path), "--device", "serial-sim://still?seed=4&pace=fast&range=8", "--dry-run")
    assert r.returncode != 0 and "is for the +-4 g range but the data were taken at +-8 g" in r.stderr
    r = flash(str(path), "--device", "serial-sim://still?seed=5&pace=fast", "--yes", "--force")
    assert r.returncode == 0 and "forced: " in r.stdout and "SIM-5" in r.stdout


def test_broken_profile_file_is_one_line(tmp_path, flash):
    bad = tmp_path / "bad.yaml"
    bad.write_text("schema_version: 1\ndevice: [\n")
    r = flash(str(bad), "--device", "serial-sim://still?pace=fast", "--yes")
    assert r.returncode != 0 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
