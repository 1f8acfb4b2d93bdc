"""Noise figures: the Allan deviation against known white noise, random walk and flicker; the noise CLI."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from accelrig.commands.noise import still_stretch
from accelrig.errors import DataError
from accelrig.estimation.allan import allan_deviation, axis_noise, noise_figures
from accelrig.recording import Recording, read_csv, write_csv
from accelrig.sim.device import simulate
from accelrig.sim.rigs.still import StillRig
from accelrig.sim.sensor import SensorModel, SimClock
from accelrig.units import STANDARD_GRAVITY

G = STANDARD_GRAVITY


def run_cli(*args):
    """A real process: proves the one-line error and exit status end to end (slow: use sparingly)."""
    return subprocess.run([sys.executable, "-m", "accelrig", *args], capture_output=True, text=True, timeout=120)


def still(density_ug: float, seconds: float, seed: int = 1, rate: float = 200.0) -> Recording:
    sensor = SensorModel(noise_density=density_ug * 1e-6 * G)
    return simulate(StillRig(), sensor, SimClock(rate, 0.004, 20e-6), seconds=seconds, seed=seed)


def test_white_noise_allan_deviation_matches_theory():
    rng = np.random.default_rng(0)
    fs, density = 100.0, 2e-3
    y = rng.standard_normal(200_000) * density * np.sqrt(fs / 2)
    c = allan_deviation(y, fs)
    expected = density / np.sqrt(2 * c.tau)
    z = (c.adev - expected) / (expected * c.relative_uncertainty)
    assert np.all(np.abs(z) < 4), z
    assert np.mean(np.abs(z)) < 1.5


@pytest.mark.parametrize("density_ug", [300.0, 230.0])   # MPU-9250, ICM-20948 datasheets
def test_simulated_density_recovered_within_5_percent_and_its_uncertainty(density_ug):
    rec = still(density_ug, seconds=120, seed=int(density_ug))
    report = noise_figures(rec)
    for axis in "xyz":
        d = report.axes[axis].density
        est_ug = d.value / G * 1e6
        assert abs(est_ug / density_ug - 1) < 0.05
        # and the stated uncertainty is honest (3 sigma)
        assert abs(est_ug - density_ug) < 3 * d.uncertainty / G * 1e6 + 0.001 * density_ug
        assert report.axes[axis].bias_instability is None     # white noise has no minimum
        assert report.axes[axis].random_walk is None


def test_random_walk_and_flicker_are_found_when_present():
    rng = np.random.default_rng(5)
    fs, n = 50.0, 50 * 4000
    white = rng.standard_normal(n) * 3e-3 * np.sqrt(fs / 2)
    k_true = 2e-4
    walk = np.cumsum(rng.standard_normal(n)) * k_true / np.sqrt(fs)
    an = axis_noise(allan_deviation(white + walk, fs))
    assert an.random_walk is not None
    assert abs(an.random_walk.value / k_true - 1) < 3 * an.random_walk.uncertainty / k_true
    assert an.density.value == pytest.approx(3e-3, rel=0.03)

    # flicker (1/f) at a known bias instability B: sigma flattens at 0.664 B
    f = np.fft.rfftfreq(n, 1 / fs)
    spec = rng.standard_normal(f.size) + 1j * rng.standard_normal(f.size)
    spec[0] = 0
    spec[1:] /= np.sqrt(f[1:])
    flicker = np.fft.irfft(spec, n)
    b_true = 3e-3
    level = allan_deviation(flicker, fs).adev[4:10].mean()
    flicker *= 0.664 * b_true / level
    an = axis_noise(allan_deviation(white + flicker, fs))
    assert an.bias_instability is not None
    # the minimum of a noisy flat curve is biased low, white noise adds a little: within -15 % .. +25 %
    assert 0.85 < an.bias_instability.value / b_true < 1.25
    assert an.bias_instability_tau > 1.0
    # read at a flat bottom, and says where: the slopes either side are flat, not a fall and a rise
    before, after = an.bias_instability_slopes
    assert abs(before) < 0.3 and abs(after) < 0.3


def test_gaps_and_short_records_are_refused():
    rec = still(300, seconds=30)
    rec.meta["gaps"] = [{"index": 2000, "missing": 5}]    # at 10 s of 30 (200 Hz)
    with pytest.raises(DataError, match="gap") as err:
        noise_figures(rec)
    # the hint names the longer side of the gap
    a, b = (float(x) for x in re.search(r"t = ([\d.]+)-([\d.]+) s", err.value.hint).groups())
    assert abs(a - rec.t[2000]) < 0.1 and abs(b - rec.t[-1]) < 0.1 and "--start/--stop" in err.value.hint
    rec = still(300, seconds=30)
    t = rec.t.copy()
    t[500:] += 1.0
    with pytest.raises(DataError, match="timestamps jump"):
        noise_figures(Recording(t, rec.acc, rec.units, {}, {}))
    with pytest.raises(DataError, match="too few|at least"):
        noise_figures(still(300, seconds=0.2))


def test_constant_axis_is_refused_in_one_line():
    t = np.arange(5000) / 200.0
    acc = np.random.default_rng(0).standard_normal((5000, 3)) * 0.03
    acc[:, 2] = G
    with pytest.raises(DataError, match="axis z never changes"):
        noise_figures(Recording(t, acc))


def test_moving_sensor_has_no_white_noise_line():
    t = np.arange(20000) / 200.0
    wave = np.column_stack([np.sin(2 * np.pi * 0.05 * t), np.cos(2 * np.pi * 0.05 * t), G + np.sin(2 * np.pi * 0.03 * t)])
    acc = wave + np.random.default_rng(1).standard_normal(wave.shape) * 1e-5   # motion dwarfs the noise
    with pytest.raises(DataError, match="no white-noise region"):
        noise_figures(Recording(t, acc))


def test_noise_cli_table_json_and_profile(tmp_path, cli):
    rec = still(300, seconds=60, seed=7)
    rec.meta["identity"] = "sim-still-7"
    path = tmp_path / "still.csv"
    write_csv(rec, path)
    r = run_cli("noise", str(path))
    assert r.returncode == 0, r.stderr
    assert "axis  density ug/sqrt(Hz)" in r.stdout
    # 80 columns like every command's table (it was a 120-column Markdown table); nothing dropped
    assert max(len(line) for line in r.stdout.splitlines()) <= 80, r.stdout
    assert "rate random walk (m/s^2)/sqrt(s)" in r.stdout and "bias instability ug (tau)" in r.stdout
    assert "one-sided" in r.stdout
    r = cli("noise", str(path), "--json")
    data = json.loads(r.stdout)
    dens = data["axes"]["z"]["density"]["value"] / G * 1e6
    assert abs(dens / 300 - 1) < 0.05
    assert len(data["arrays"]["tau"]) == len(data["arrays"]["adev_x"]) > 5

    # store into a profile of the same device; refuse another device's profile without --force
    from accelrig.profiles import load_profile, profile_from_result, save_profile
    from tests.test_profile_io import make_result

    prof = tmp_path / "p.yaml"
    save_profile(profile_from_result(make_result(), rec), prof)
    r = cli("noise", str(path), "--profile", str(prof))
    assert r.returncode == 0, r.stderr
    stored = load_profile(prof).noise
    assert stored["axes"]["x"]["density"]["value"] == pytest.approx(300e-6 * G, rel=0.05)
    assert stored["recording_hash"] == read_csv(path).content_hash()

    other = tmp_path / "other.yaml"
    save_profile(profile_from_result(make_result(), rec, device={"identity": "someone-else"}), other)
    before = other.read_text()
    r = cli("noise", str(path), "--profile", str(other))
    assert r.returncode != 0
    assert r.stderr.count("\n") == 1 and "someone-else" in r.stderr and "--force" in r.stderr
    assert other.read_text() == before


def with_added(rec: Recording, extra: np.ndarray) -> Recording:
    return Recording(rec.t, rec.acc + extra, rec.units, dict(rec.channels), dict(rec.meta))


def test_sinusoid_hump_is_not_bias_instability():
    """White noise plus a 12 s oscillation (0.5 mg): the dip before its hump is no flat bottom."""
    rng = np.random.default_rng(3)
    fs, density = 100.0, 300e-6 * G
    t = np.arange(int(600 * fs)) / fs
    white = rng.standard_normal(t.size) * density * np.sqrt(fs / 2)
    an = axis_noise(allan_deviation(white + 5e-3 * np.sin(2 * np.pi * t / 12.0), fs))
    assert an.bias_instability is None and an.bias_instability_slopes is None
    assert any("hump" in n and "periodic" in n for n in an.notes), an.notes
    assert abs(an.density.value - density) < 3 * an.density.uncertainty


def test_still_white_noise_is_accepted_whole():
    rec = still(300, seconds=120, seed=11)
    start, stop = still_stretch(rec.to_si())
    report = noise_figures(rec, (start, stop))
    assert report.still_segment["of_total"] - report.still_segment["seconds"] < 1.0
    for axis in "xyz":
        d = report.axes[axis].density
        assert abs(d.value - 300e-6 * G) < 3 * d.uncertainty + 0.001 * 300e-6 * G


def test_hand_rotation_is_refused():
    """Turned by hand: gravity sweeps round the sensor, a few seconds per quarter turn."""
    t = np.arange(int(60 * 200)) / 200.0
    angle = 0.5 * t + 0.3 * np.sin(1.3 * t)
    acc = G * np.column_stack([np.sin(angle), np.zeros_like(t), np.cos(angle)])
    acc += np.random.default_rng(2).standard_normal(acc.shape) * 0.03
    with pytest.raises(DataError, match="moving throughout|turned") as e:
        still_stretch(Recording(t, acc))
    assert "resting" in e.value.hint and "\n" not in str(e.value)


def test_knock_is_excluded_and_stated():
    """Still for 120 s but knocked for 2 s at t = 60 s: read on the longer still side, within 10 %."""
    rec = still(300, seconds=120, seed=4)
    tt = rec.t - 60.0
    knock = np.zeros_like(rec.acc)
    inside = (tt >= 0) & (tt < 2)
    knock[inside, 0] = 3.0 * np.sin(2 * np.pi * 8 * tt[inside]) * np.exp(-tt[inside])
    knocked = with_added(rec, knock)
    assert noise_figures(knocked).axes["x"].density.value > 2 * 300e-6 * G     # read whole, it is wrong
    start, stop = still_stretch(knocked.to_si())
    assert stop < 60.0 or start > 62.0
    report = noise_figures(knocked, (start, stop))
    assert report.still_segment["seconds"] > 55 and report.still_segment["of_total"] == pytest.approx(120, abs=0.1)
    for axis in "xyz":
        assert abs(report.axes[axis].density.value / (300e-6 * G) - 1) < 0.10


def test_slow_bump_is_refused_with_when():
    """A 2 s push (0.3 m/s^2, below the motion threshold) while resting: the detector calls it moved."""
    rec = still(300, seconds=120, seed=5)
    tt = rec.t - 60.0
    bump = np.zeros_like(rec.acc)
    inside = (tt >= 0) & (tt < 2)
    bump[inside, 0] = 0.3 * np.sin(np.pi * tt[inside] / 2)
    with pytest.raises(DataError, match=r"not still: .*moved .*t = 6\d\.\d s"):
        still_stretch(with_added(rec, bump).to_si())


def test_real_xsens_multipose_refused_by_cli():
    path = Path(__file__).parent / "data" / "imutk-xsens-multipose.csv"
    r = run_cli("noise", str(path))
    assert r.returncode != 0 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and "turned" in r.stderr and "resting" in r.stderr
