"""A chip with flashed offsets already removes part of the bias: the host must not remove it twice."""

import numpy as np

from accelrig.cli import main
from accelrig.profiles import load_profile
from accelrig.recording import read_csv
from accelrig.units import STANDARD_GRAVITY

CHIP = "i2c-sim://mpu9250?pace=fast&rate=200&seed=3&range=2"


def test_profile_applied_to_data_from_a_flashed_chip(tmp_path):
    faces, profile_path = tmp_path / "faces.csv", tmp_path / "p.yaml"
    assert main(["record", CHIP + "&rig=static", "-o", str(faces)]) == 0
    assert main(["calibrate", "static", str(faces), "-o", str(profile_path)]) == 0
    profile = load_profile(profile_path)
    assert np.max(np.abs(profile.correction.bias)) > 0.05  # a bias worth flashing

    # the driver re-applies (flashes) the profile's offsets on connect
    flashed = tmp_path / "flashed.csv"
    assert main(["record", CHIP + f"&rig=still&profile={profile_path}", "--seconds", "4", "-o", str(flashed)]) == 0
    rec = read_csv(flashed)
    removed = np.asarray(rec.meta["hardware_bias_removed"])
    np.testing.assert_allclose(removed, profile.correction.bias, atol=0.0097)  # within one register step

    out = tmp_path / "cal.csv"
    assert main(["profile", "apply", str(profile_path), str(flashed), "-o", str(out)]) == 0
    mean = read_csv(out).acc.mean(axis=0)
    # still, +z up: calibrated reads (0, 0, g); subtracting the bias twice would be off by |b|
    np.testing.assert_allclose(mean, [0, 0, STANDARD_GRAVITY], atol=0.01)

    # calibrating again on the flashed chip gives the profile of the sensor at power-up
    faces2, again = tmp_path / "faces2.csv", tmp_path / "again.yaml"
    assert main(["record", CHIP + f"&rig=static&profile={profile_path}", "-o", str(faces2)]) == 0
    assert main(["calibrate", "static", str(faces2), "-o", str(again)]) == 0
    second = load_profile(again)
    u = np.hypot(profile.correction.bias_uncertainty, second.correction.bias_uncertainty)
    assert np.all(np.abs(second.correction.bias - profile.correction.bias) < 4 * u + 1e-3)
    assert any("flashed offsets" in w for w in second.data["warnings"])
