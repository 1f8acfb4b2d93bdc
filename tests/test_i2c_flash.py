"""Flashing a profile's bias into the chips' offset registers, end to end through the emulators."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from accelrig.acquisition.chips.base import OFFSET_STEP, offset_value  # noqa: E402
from accelrig.acquisition.driver import driver_for  # noqa: E402
from accelrig.acquisition.session import Session  # noqa: E402
from accelrig.acquisition.url import DeviceURL  # noqa: E402
from accelrig.errors import DeviceError, ProfileError  # noqa: E402
from accelrig.profiles import profile_from_result, save_profile  # noqa: E402
from accelrig.profiles.flash import flash_url_profile, plan_flash  # noqa: E402
from accelrig.result import CalibrationResult, Correction  # noqa: E402
from accelrig.sim.chips import EMULATORS  # noqa: E402
from accelrig.sim.chips import mpu9250 as mpu_emulator  # noqa: E402
from accelrig_drivers.i2c_sim import I2CSimDriver  # noqa: E402

G_UP = np.array([0.0, 0.0, 9.80665])
# White noise sd per sample (m/s^2) where a 1 s mean is compared with a register step: at the
# datasheet density (0.047 m/s^2 at 500 Hz) the mean's sd, 0.002, is half the 0.004 tolerance,
# so the checks would pass or fail with the seed's noise draw rather than with the registers.
QUIET = "noise=0.01"


def profile_for(driver, correction=None, **device_overrides):
    """A real Profile (accelrig.profiles) for the opened device, by default with its true correction."""
    correction = correction or driver.emulator.sensor.correction()
    result = CalibrationResult(procedure="truth", method="simulator ground truth", model="C (raw - b)",
                               correction=correction, parameters={})
    profile = profile_from_result(result, device=driver.info.to_dict())
    profile.data["device"].update(device_overrides)
    profile.validate()
    return profile


def mean_reading(driver, seconds, settle=0.05):
    """Mean raw acceleration (m/s^2) over ``seconds``, after dropping ``settle`` s of samples."""
    clock = driver.clock
    start = clock.now()
    blocks = []
    while clock.now() < start + settle + seconds:
        blocks.extend(driver.read(timeout=0.1))
    t = np.concatenate([b.t for b in blocks])
    acc = np.concatenate([b.acceleration() for b in blocks])
    return acc[t > start + settle].mean(axis=0)


@pytest.mark.parametrize("chip", ["mpu9250", "icm20948"])
def test_flash_then_a_still_sensor_reads_the_offset_removed_within_one_step(chip):
    with driver_for(f"i2c-sim://{chip}?rig=still&pace=fast&rate=500&seed=3&{QUIET}") as driver:
        sensor = driver.emulator.sensor
        expected_without_offset = sensor.response_matrix @ G_UP
        before = mean_reading(driver, 1.0)
        assert np.all(np.abs(before - expected_without_offset - sensor.offset) < 0.01)
        profile = profile_for(driver)
        factory = driver.chip.read_offset_words()
        assert {w & 1 for w in factory} == {0, 1}      # this part's trim has the reserved bit both ways
        plan = plan_flash(driver, profile)
        assert driver.chip.read_offset_words() == factory          # planning writes nothing
        assert len(plan.writes) == 3 and all(w.current != w.new for w in plan.writes)
        new_words = [int(w.new, 16) for w in plan.writes]
        assert [w & 1 for w in new_words] == [w & 1 for w in factory]   # reserved bit kept
        report = driver.flash(plan)
        assert report.verified
        assert driver.chip.read_offset_words() == new_words
        after = mean_reading(driver, 1.0)
        remaining = after - expected_without_offset
        assert np.all(np.abs(remaining) <= OFFSET_STEP)
        np.testing.assert_allclose(remaining, report.residual["bias_remaining_m_s2"], atol=0.004)
        # Host side: the gain/misalignment matrix and the sub-step remainder finish the job.
        calibrated = np.asarray(report.residual["matrix"]) @ (after - report.residual["bias_remaining_m_s2"])
        np.testing.assert_allclose(calibrated, G_UP, atol=0.004)


def test_mismatched_profiles_are_refused_unless_forced():
    with driver_for("i2c-sim://mpu9250?rig=still&pace=fast&rate=200&range=4") as driver:
        for overrides, message in [({"chip": "icm20948"}, "chip 'icm20948'"),
                                   ({"chip": None}, "which chip"),
                                   ({"range_g": 2.0, "scale": None}, "2 g range"),
                                   ({"identity": "i2c-1-0x69"}, "i2c-1-0x69")]:
            with pytest.raises(ProfileError, match=message):
                plan_flash(driver, profile_for(driver, **overrides))
        plan = plan_flash(driver, profile_for(driver, chip="icm20948", identity="i2c-1-0x69"), force=True)
        forced = [note for note in plan.notes if note.startswith("forced")]
        assert len(forced) == 2 and any("icm20948" in f for f in forced) and any("i2c-1-0x69" in f for f in forced)
        # A profile that does not name its device is flashed, with the warning in the plan.
        plan = plan_flash(driver, profile_for(driver, identity=None))
        assert any("cannot check the profile belongs to this device" in note for note in plan.notes)


def test_flashing_twice_does_not_subtract_twice():
    with driver_for("i2c-sim://icm20948?rig=still&pace=fast&rate=200") as driver:
        profile = profile_for(driver)
        first = driver.flash(plan_flash(driver, profile))
        second_plan = plan_flash(driver, profile)
        assert any("written since the reset" in n for n in second_plan.notes)
        second = driver.flash(second_plan)
        assert [w.current for w in first.readback] == [w.current for w in second.readback]


def test_offsets_are_reapplied_on_connect_and_lost_on_power_cycle(tmp_path):
    url = f"i2c-sim://mpu9250?rig=still&pace=fast&rate=500&seed=4&{QUIET}"
    with driver_for(url) as plain:
        save_profile(profile_for(plain), tmp_path / "sensor.yaml")
    with_profile = f"{url}&profile={tmp_path / 'sensor.yaml'}"
    for driver in (I2CSimDriver(DeviceURL.parse(with_profile)), driver_for(with_profile)):
        with driver:
            flash_url_profile(driver)
            applied = driver.info.offsets_applied
            sensor = driver.emulator.sensor
            remaining = mean_reading(driver, 1.0) - sensor.response_matrix @ G_UP
            assert np.all(np.abs(remaining) <= OFFSET_STEP)
            np.testing.assert_allclose(remaining, applied["bias_remaining_m_s2"], atol=0.004)
            assert driver.chip.read_offset_words() != driver.factory_words
            driver.emulator.power_cycle()                         # volatile: back to the factory trim
            assert driver.chip.read_offset_words() == driver.emulator.factory_words == driver.factory_words


def test_a_profile_for_another_device_stops_the_connect(tmp_path):
    with driver_for("i2c-sim://mpu9250?rig=still&pace=fast&rate=200&seed=1") as other:
        save_profile(profile_for(other), tmp_path / "other.yaml")
    with pytest.raises(ProfileError, match="i2c-sim-mpu9250-seed1"):
        Session.open_and_start(f"i2c-sim://mpu9250?rig=still&pace=fast&rate=200&seed=2&profile={tmp_path / 'other.yaml'}",
                               prepare=flash_url_profile)


def test_a_bias_beyond_the_registers_is_refused_and_nothing_written():
    with driver_for("i2c-sim://mpu9250?rig=still&pace=fast&rate=200") as driver:
        huge = Correction(np.eye(3), [200.0, 0.0, 0.0], np.zeros((12, 12)))
        with pytest.raises(DeviceError, match="15-bit range"):
            plan_flash(driver, profile_for(driver, correction=huge))
        assert driver.chip.read_offset_words() == driver.factory_words


class StubbornOffsets(mpu_emulator.MPU9250Emulator):
    """A part whose offset registers ignore writes (the layout is not what the driver assumes)."""

    layout = replace(mpu_emulator.LAYOUT, read_only=mpu_emulator.LAYOUT.read_only
                     | {(0, r) for r in (0x77, 0x78, 0x7A, 0x7B, 0x7D, 0x7E)})


def test_a_write_that_does_not_read_back_fails_loudly(monkeypatch):
    monkeypatch.setitem(EMULATORS, "mpu9250", StubbornOffsets)
    with driver_for("i2c-sim://mpu9250?rig=still&pace=fast&rate=200") as driver:
        plan = plan_flash(driver, profile_for(driver))
        with pytest.raises(DeviceError, match="XA_OFFSET .* reads back"):
            driver.flash(plan)
        assert driver.chip.read_offset_words() == driver.factory_words


def test_a_plan_is_bound_to_its_connection():
    with driver_for("i2c-sim://mpu9250?rig=still&pace=fast&rate=200") as one:
        plan = plan_flash(one, profile_for(one))
    with driver_for("i2c-sim://mpu9250?rig=still&pace=fast&rate=200") as other:
        with pytest.raises(DeviceError, match="another connection"):
            other.flash(plan)
        assert offset_value(other.chip.read_offset_words()[0]) == offset_value(other.factory_words[0])


def test_static_calibration_through_the_emulated_chip_then_flash_removes_the_true_offset():
    """The whole path: record the six faces from the emulated chip, calibrate, keep the profile,
    flash it on the next connect of the same part, and read it still."""
    from accelrig.acquisition.recorder import record
    from accelrig.procedures.static.procedure import calibrate_static

    with driver_for("i2c-sim://mpu9250?rig=static&pace=fast&rate=200&seed=3") as driver:
        recording = record(driver)
    result = calibrate_static(recording)
    profile = profile_from_result(result, recording)
    with driver_for("i2c-sim://mpu9250?rig=still&pace=fast&rate=500&seed=3") as driver:   # same part, at rest
        sensor = driver.emulator.sensor
        report = driver.flash(plan_flash(driver, profile))
        remaining = mean_reading(driver, 1.0) - sensor.response_matrix @ G_UP
    u_bias = profile.correction.bias_uncertainty
    assert np.all(np.abs(sensor.offset - profile.correction.bias) < 4 * u_bias + 1e-3)
    assert np.all(np.abs(remaining) <= OFFSET_STEP)
    np.testing.assert_allclose(remaining, report.residual["bias_remaining_m_s2"], atol=4 * u_bias.max() + 0.004)
