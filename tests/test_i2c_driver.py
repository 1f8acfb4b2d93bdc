"""The real I2C driver over emulated chips: throughput, timing, overflow, identity, errors."""

from __future__ import annotations

import sys
from itertools import pairwise

import numpy as np
import pytest

from accelrig.acquisition.chips.icm20948 import ICM20948  # noqa: E402
from accelrig.acquisition.chips.stream import DELIVER_EVERY, MAX_SLEW, RATE_TOLERANCE  # noqa: E402
from accelrig.acquisition.chips.timing import EmulatedClock  # noqa: E402
from accelrig.acquisition.driver import driver_for  # noqa: E402
from accelrig.acquisition.recorder import record  # noqa: E402
from accelrig.acquisition.registers import RegisterAccessor  # noqa: E402
from accelrig.acquisition.url import DeviceURL  # noqa: E402
from accelrig.errors import DeviceError, MissingExtraError  # noqa: E402
from accelrig.sim.chips import EMULATORS, EmulatedBus  # noqa: E402
from accelrig.sim.chips.ramp import RampRig  # noqa: E402
from accelrig.sim.rigs import RIGS  # noqa: E402
from accelrig.sim.rigs.still import StillRig  # noqa: E402
from accelrig.sim.sensor import SensorModel  # noqa: E402
from accelrig_drivers.i2c import I2CDriver  # noqa: E402
from accelrig_drivers.i2c_sim import I2CSimDriver  # noqa: E402


def true_times(counts, scale):
    return RampRig().decode(counts[:, 0] * scale, None)


def emulated(chip="mpu9250", rig=None, sensor=None, rate_error=0.004, jitter=0.0005, seed=0, **emulator_options):
    clock = EmulatedClock(wake_jitter=jitter, rng=np.random.default_rng(seed))
    sensor = sensor or SensorModel.random(np.random.default_rng(seed))
    emulator = EMULATORS[chip](rig or StillRig(), sensor, clock, seed=seed, rate_error=rate_error, **emulator_options)
    bus = EmulatedBus(clock)
    bus.attach(0x68, emulator)
    return bus, emulator, clock


def open_driver(query, chip="mpu9250", **kwargs):
    bus, emulator, clock = emulated(chip, **kwargs)
    driver = I2CDriver(DeviceURL.parse(f"i2c://1/0x68?chip={chip}&{query}"), bus=bus, clock=clock)
    driver.open()
    return driver, emulator, clock


def collect(driver, clock, seconds):
    end = clock.now() + seconds
    blocks = []
    while clock.now() < end:
        blocks.extend(driver.read(timeout=0.1))
    return blocks


def ideal_16g():
    return SensorModel(noise_density=0.0, range_g=16.0)


@pytest.mark.parametrize("chip", ["mpu9250", "icm20948"])
def test_sustains_2048_hz_for_60_s_of_emulated_real_time_with_no_unexplained_loss(chip):
    driver, emulator, clock = open_driver("rate=2048", chip=chip, rate_error=0.004)
    stream = driver.stream
    assert driver.info.nominal_rate == 2048.0
    t_start = clock.now()
    blocks = collect(driver, clock, 60.0)
    assert clock.now() - t_start >= 60.0
    # Nothing lost between chip and driver: every frame the chip put in the FIFO was read or is still there.
    assert stream.overflows == 0 and emulator.bytes_lost == 0
    assert emulator.frames_into_fifo == stream.frames_read + len(emulator.fifo) // 6
    # Nothing lost between FIFO and blocks: the resampler emitted exactly the outputs its input supports.
    rs = stream.resampler
    first = -(-((rs.taps_per_phase - 1) * rs.up) // rs.down)
    last = ((stream.frames_read - 1) * rs.up) // rs.down
    n_out = sum(b.n for b in blocks)
    assert n_out == last - first + 1
    assert all(b.gap_before == 0 for b in blocks)
    assert all(b.counter == a.counter + a.n for a, b in pairwise(blocks))
    # The delivered rate is measured, and right: 2048 Hz on a chip 0.4 % fast.
    true_rate = 2048 * 1.004
    assert abs(driver.delivered_rate - true_rate) < max(4 * stream.delivered_rate_uncertainty, 1e-3)
    assert abs(driver.delivered_rate - true_rate) < 0.05
    # Sample times lie on one straight line (no steps between blocks once the fit has settled).
    t = np.concatenate([b.t for b in blocks])
    late = slice(len(t) // 6, None)
    k = np.arange(len(t))[late]
    line = np.polyval(np.polyfit(k, t[late], 1), k)
    assert np.max(np.abs(t[late] - line)) < 20e-6


@pytest.mark.parametrize("chip, rate", [("mpu9250", 500), ("icm20948", 2048), ("mpu9250", 2000)])
def test_sample_times_are_when_the_samples_were_taken(chip, rate):
    driver, emulator, clock = open_driver(f"rate={rate}&range=16", chip=chip, rig=RampRig(), sensor=ideal_16g())
    blocks = collect(driver, clock, 8.0)
    counts = np.concatenate([b.counts for b in blocks])
    t = np.concatenate([b.t for b in blocks])
    error = t - true_times(counts, driver.info.scale)
    settled = t > t[0] + 1.0
    half_period = 0.5 / rate
    assert abs(np.mean(error[settled])) < 0.1 * half_period + 20e-6
    assert np.percentile(np.abs(error[settled]), 99) < half_period + 0.2e-3


@pytest.mark.parametrize("chip, rate, stall", [("mpu9250", 500, 0.5), ("icm20948", 2048, 0.06)])
def test_overflow_is_seen_the_fifo_reset_and_the_gap_sized(chip, rate, stall):
    driver, emulator, clock = open_driver(f"rate={rate}&range=16", chip=chip, rig=RampRig(), sensor=ideal_16g())
    before = collect(driver, clock, 2.0)
    clock.sleep(stall)                                  # the host stalls: the FIFO overflows
    after = collect(driver, clock, 2.0)
    assert emulator.bytes_lost > 0
    assert driver.stream.overflows == 1
    gaps = [b for b in after if b.gap_before != 0]
    assert len(gaps) == 1 and all(b.gap_before == 0 for b in before)
    gap_block = gaps[0]
    previous = after[after.index(gap_block) - 1] if after.index(gap_block) else before[-1]
    t_last = true_times(previous.counts[-1:], driver.info.scale)[0]
    t_next = true_times(gap_block.counts[:1], driver.info.scale)[0]
    true_gap = (t_next - t_last) * rate * (1 + emulator.rate_error) - 1
    assert abs(gap_block.gap_before - true_gap) <= 1.5        # +-1 sample, plus decoding resolution
    assert gap_block.counter == previous.counter + previous.n + gap_block.gap_before


def test_a_bypass_rate_that_does_not_hold_is_detected_not_assumed():
    # The MPU-9250's FIFO rate in filter bypass is uncertain; an emulated part filling at 1 kHz
    # must stop the stream with an explanation, not deliver mis-timed "2048 Hz" data.
    driver, _, clock = open_driver("rate=2048", bypass_fifo_rate=1000.0)
    with pytest.raises(DeviceError, match="FIFO fills at 100[0-9].* not the 4000 Hz"):
        collect(driver, clock, 3.0)


def test_who_am_i_variants_are_accepted_and_strangers_refused():
    driver, _, _ = open_driver("rate=200", who_am_i=0x73)
    assert driver.info.who_am_i == 0x73 and driver.info.part == "MPU-9255"
    with pytest.raises(DeviceError, match="WHO_AM_I=0x12"):
        open_driver("rate=200", who_am_i=0x12)
    bus, _, clock = emulated("mpu9250")
    wrong_chip = I2CDriver(DeviceURL.parse("i2c://1/0x68?chip=icm20948"), bus=bus, clock=clock)
    with pytest.raises(DeviceError, match="not a ICM-20948|bank select"):
        wrong_chip.open()


def test_icm_configured_without_waking_fails_its_read_back():
    bus, _, clock = emulated("icm20948")
    chip = ICM20948(RegisterAccessor(bus, 0x68, bank_select=(0x7F, 4)), clock)
    chip.reset()
    with pytest.raises(DeviceError, match="ACCEL_FS_SEL .* reads back"):
        chip.set_range_code(2)


def test_i2c_sim_url_runs_the_real_driver_and_records():
    with driver_for("i2c-sim://icm20948?rig=still&pace=fast&rate=250&seed=2&range=4") as driver:
        assert isinstance(driver, I2CSimDriver)
        rec = record(driver, seconds=3.0)
    assert rec.meta["chip"] == "icm20948" and rec.meta["range_g"] == 4.0
    assert rec.meta["nominal_rate"] == pytest.approx(1125 / 5)     # the nearest DLPF rate to 250 Hz
    assert rec.meta["gaps"] == []
    assert abs(rec.acc[:, 2].mean() - 9.80665) < 0.5
    assert rec.meta["truth"]["rate_error"] == 0.004


def test_i2c_sim_realtime_pace_uses_the_wall_clock():
    with driver_for("i2c-sim://mpu9250?rig=still&rate=1000") as driver:
        blocks = []
        while sum(b.n for b in blocks) < 100:
            blocks.extend(driver.read(timeout=0.05))
    t = np.concatenate([b.t for b in blocks])
    assert np.all(np.diff(t) > 0)


@pytest.mark.parametrize("url, message", [
    ("i2c://one/0x68", "bus and an address"),
    ("i2c://1/0x99", "outside 0x03"),
    ("i2c://1/0x68?chip=bmi160", "chip="),
    ("i2c://1/0x68?rang=4", "unknown option"),
    ("i2c-sim://mpu9250?range=3&pace=fast", "not a MEMS range"),
    ("i2c-sim://lis3dh?pace=fast", "no chip"),
    ("i2c-sim://mpu9250?rig=nope", "unknown simulated rig"),
])
def test_bad_urls_are_one_clear_device_error(url, message):
    with pytest.raises(DeviceError, match=message):
        driver_for(url).open()


def test_missing_bus_is_a_device_error_and_missing_smbus2_a_missing_extra(monkeypatch):
    with pytest.raises(DeviceError, match="cannot open I2C bus 97"):
        driver_for("i2c://97/0x68").open()
    monkeypatch.setitem(sys.modules, "smbus2", None)
    with pytest.raises(MissingExtraError, match=r"accelrig\[i2c\]"):
        driver_for("i2c://1/0x68").open()
    with pytest.raises(MissingExtraError):
        I2CDriver.discover()


def test_discover_lists_buses_without_probing():
    found = I2CDriver.discover()
    assert all(u.startswith("i2c://") and u.endswith("/0x68") for u in found)
    assert I2CSimDriver.discover() == ["i2c-sim://icm20948?rig=static", "i2c-sim://mpu9250?rig=static"]


def test_a_fifo_larger_than_the_datasheet_figure_is_noticed_by_counting():
    # One source gives the ICM-20948 a 4 KB FIFO: the driver reads FIFO_COUNT rather than assuming 512 B.
    driver, emulator, clock = open_driver("rate=2048", chip="icm20948", fifo_capacity=4096)
    collect(driver, clock, 0.5)
    clock.sleep(0.1)                                # 450 frames = 2700 B: fits in 4 KB, not in 512 B
    blocks = collect(driver, clock, 0.5)
    assert driver.stream.overflows == 0 and emulator.bytes_lost == 0
    assert all(b.gap_before == 0 for b in blocks)
    assert driver.stream.max_fifo_count > 512
    assert any("larger FIFO" in note for note in driver.stream.notes)


def test_cli_records_from_an_emulated_chip_and_reports_a_missing_bus_in_one_line(tmp_path, capsys):
    from accelrig.cli import main
    from accelrig.recording import read_csv

    out = tmp_path / "chip.csv"
    assert main(["record", "i2c-sim://mpu9250?rig=still&pace=fast&rate=2048&seed=1", "--seconds", "2",
                 "-o", str(out)]) == 0
    rec = read_csv(out)
    assert rec.meta["chip"] == "mpu9250" and rec.meta["nominal_rate"] == 2048.0
    assert abs(len(rec) - 2 * 2048 * 1.004) <= 2
    assert capsys.readouterr().err.startswith(f"accelrig record: kept {len(rec)} samples")   # what was recorded
    assert main(["record", "i2c://97/0x68?chip=mpu9250", "--seconds", "1", "-o", str(tmp_path / "no.csv")]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot open I2C bus 97" in err[0]
    assert not (tmp_path / "no.csv").exists()


@pytest.mark.parametrize("rig_name", sorted(RIGS))
def test_every_simulated_rig_is_reachable_through_the_emulated_chip(rig_name):
    url = f"i2c-sim://mpu9250?rig={rig_name}&pace=fast&rate=500&range=16&truth=ideal&noise=0&seed=1"
    with driver_for(url) as driver:
        blocks = collect(driver, driver.clock, 1.0)
        rig = driver.rig
    t = np.concatenate([b.t for b in blocks])
    acc = np.concatenate([b.acceleration() for b in blocks])
    assert len(t) > 400
    # The chip sampled the rig when the driver says it did (rig time 0 is the emulated power-on).
    expected = rig.specific_force(t)
    assert np.max(np.abs(acc - expected)) < 0.02 + 0.05 * np.max(np.abs(expected))


@pytest.mark.parametrize("chip, rate, jitter", [("mpu9250", 1000, 0.0005), ("icm20948", 1125, 0.003)])
def test_overflows_under_stalled_reads_keep_times_continuous_and_every_sample_accounted(chip, rate, jitter):
    # A host that keeps stalling (a loaded machine): every stall overflows the FIFO.  Each
    # overflow must be one gap of the samples really lost, sized in whole periods, and the
    # times between gaps one period apart, however few polls a stretch between resets has.
    driver, emulator, clock = open_driver(f"rate={rate}", chip=chip, jitter=jitter, seed=5)
    stream = driver.stream
    stream.start()
    produced_before = emulator.samples_taken - len(emulator.fifo) // 6     # index of the first frame kept
    blocks = collect(driver, clock, 2.0)
    rng = np.random.default_rng(1)
    stalls = 40
    for _ in range(stalls):
        clock.sleep(rng.uniform(0.1, 0.6))           # the reader is late: the FIFO overflows
        blocks.extend(collect(driver, clock, rng.uniform(0.03, 0.3)))   # a few polls, then the next stall
    blocks.extend(collect(driver, clock, 1.0))
    assert stream.overflows == stalls
    gaps = [b.gap_before for b in blocks]
    assert sum(g != 0 for g in gaps) == stalls and min(gaps) >= 0   # every gap sized (none unknown)
    # exact accounting: every sample the chip took since was delivered, is in a gap, or is still in the FIFO
    produced = emulator.samples_taken - len(emulator.fifo) // 6 - produced_before
    assert sum(b.n for b in blocks) + sum(gaps) == produced
    assert all(b.counter == a.counter + a.n + b.gap_before for a, b in pairwise(blocks))
    # continuity: one measured period between samples, (gap + 1) periods across a gap; within the
    # rate tolerance while the first second measures the rate, within 2 % (the slew) after it
    period = 1.0 / driver.delivered_rate
    t = np.concatenate([b.t for b in blocks])
    expected = np.concatenate([np.r_[g + 1, np.ones(b.n - 1)] for b, g in zip(blocks, gaps, strict=True)])[1:]
    deviation = np.abs(np.diff(t) / period - expected)
    settled = t[1:] > t[0] + 1.0
    assert np.max(deviation) < RATE_TOLERANCE + MAX_SLEW + 0.01
    assert np.max(deviation[settled]) < 0.02


def test_a_read_joins_its_polls_into_one_block_and_an_error_comes_after_their_samples():
    driver, emulator, clock = open_driver("rate=2048&range=16", rig=RampRig(), sensor=ideal_16g())
    collect(driver, clock, 1.0)                          # the rate measured, the filter filled
    stream = driver.stream
    one_poll = 2048 * stream.poll_interval                # about 15 samples: 7.1 ms at 2048 Hz
    polls = round(DELIVER_EVERY / stream.poll_interval)
    start = clock.now()
    blocks = driver.read(timeout=0.1)
    assert len(blocks) == 1 and blocks[0].gap_before == 0
    assert (polls - 1) * stream.poll_interval < clock.now() - start < polls * stream.poll_interval + 0.005
    assert abs(blocks[0].n - polls * one_poll) < one_poll  # every poll's samples, in one block
    # The bus fails on the third poll of the next read: the two polls' samples still arrive...
    failing, calls = emulator.read, []

    def read_then_fail(length):
        calls.append(length)
        if len(calls) > 6:                              # 3 register reads per poll
            raise OSError(121, "Remote I/O error")
        return failing(length)

    emulator.read = read_then_fail
    last = blocks[-1]
    blocks = driver.read(timeout=0.1)
    assert len(blocks) == 1 and blocks[0].counter == last.counter + last.n
    assert abs(blocks[0].n - 2 * one_poll) < one_poll
    # ...and the next read raises the error, naming the register that failed.
    with pytest.raises(DeviceError, match="failed: .*Remote I/O error"):
        driver.read(timeout=0.1)
