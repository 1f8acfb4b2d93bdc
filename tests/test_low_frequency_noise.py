"""Noise slower than the longest batch-means blocks (issue 18): a power law fitted to the residuals'
lowest octaves, carried to the record's length with each estimate's influence function.

Batch means over 20 blocks see a 1/f^beta noise below the block's resolution as flat; an estimate
whose column changes slowly over the record (a trend, a curvature: the wheel's centripetal term) takes
most of its error from below it, so the batch-means u alone is too small.  The noise here is drawn by
shaping a spectrum with an FFT over four times the record (its own equations, not the estimator's)."""

import numpy as np

from accelrig.estimation.residuals import (
    LOW_FIRST_ORDINATE,
    LOW_OCTAVES_ABOVE,
    MIN_BLOCKS,
    block_scores,
    fit_power_law,
    low_frequency_covariance,
    sandwich_covariance,
)

N = 4000


def _noise(rng, beta, corner):
    """White (sd 1) plus a part with spectrum (corner / f)^beta times the white one (f in cycles/sample)."""
    m = 4 * N
    f = np.fft.rfftfreq(m)
    f[0] = f[1]
    slow = np.fft.irfft(np.fft.rfft(rng.standard_normal(m)) * (corner / f) ** (beta / 2), m)
    start = int(rng.integers(0, m - N))
    return rng.standard_normal(N) + slow[start:start + N]


def _coverage(beta, corner, draws, seed):
    """Coverage of +-2u for a trend and a curvature over the record, batch means alone and with the
    low-frequency term; plus a sine's (a fast column, which the low frequencies must not touch)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(-1.0, 1.0, N)
    x = np.column_stack([np.ones(N), t, 1.5 * t**2 - 0.5, np.sin(2 * np.pi * 40 * t)])
    normal = x.T @ x
    bread = np.linalg.inv(normal)
    influence = x @ bread
    influence[:, 0] -= 1.0 / N           # the noise's mean over the record is the constant's own
    block = N // MIN_BLOCKS
    old, new = [], []
    for _ in range(draws):
        e = _noise(rng, beta, corner)
        estimate = bread @ x.T @ e
        residuals = e - x @ estimate
        batch = sandwich_covariance(normal, block_scores(x, residuals, block), block).covariance
        law = fit_power_law(residuals, LOW_FIRST_ORDINATE, MIN_BLOCKS * 2**LOW_OCTAVES_ABOVE)[0]
        widened = batch + low_frequency_covariance(influence, law, MIN_BLOCKS)
        old.append(np.abs(estimate) <= 2 * np.sqrt(np.diag(batch)))
        new.append(np.abs(estimate) <= 2 * np.sqrt(np.diag(widened)))
    return np.mean(old, axis=0), np.mean(new, axis=0)


def test_a_pink_noise_below_the_blocks_is_carried_into_u():
    old, new = _coverage(beta=0.5, corner=0.02, draws=80, seed=4)
    slow = slice(1, 3)                    # the trend and the curvature
    assert np.mean(old[slow]) < 0.85      # batch means alone: about 75 %
    assert 0.88 <= np.mean(new[slow]) <= 0.99
    assert abs(new[3] - old[3]) <= 0.05   # a column at 40 cycles per record is the batch means' own


def test_white_noise_gains_little():
    old, new = _coverage(beta=0.0, corner=1.0, draws=60, seed=5)
    assert np.all(new >= old)
    assert np.mean(new[1:]) <= 0.99


def test_the_power_law_is_found_where_it_is_and_not_in_white_noise():
    rng = np.random.default_rng(11)
    pink = np.column_stack([_noise(rng, 1.0, 0.01) for _ in range(3)])
    law = fit_power_law(pink, LOW_FIRST_ORDINATE, 80)
    assert all(w.found for w in law)
    assert 0.6 <= law[0].beta <= 1.4
    p_values = [fit_power_law(rng.standard_normal((N, 3)), LOW_FIRST_ORDINATE, 80)[0].p_value for _ in range(20)]
    assert sum(p < 0.01 for p in p_values) <= 2
    # no power law, nothing added
    flat = fit_power_law(rng.standard_normal((N, 1)), LOW_FIRST_ORDINATE, 80)[0]
    flat.level = 0.0
    assert not np.any(low_frequency_covariance(np.ones((N, 2)) / N, flat, MIN_BLOCKS))


def test_the_wheel_says_how_the_low_frequencies_entered_u():
    from accelrig.procedures.wheel.procedure import calibrate_wheel
    from accelrig.sim.device import simulate
    from accelrig.sim.rigs.wheel import WheelRig
    from accelrig.sim.sensor import SensorModel, SimClock

    rig = WheelRig(radius=0.28, duration=60.0)
    sensor = SensorModel(offset=np.array([0.3, -0.2, 0.25]), gain=np.array([0.98, 1.0, 1.02]), range_g=4.0,
                         noise_density=SensorModel.noise_density_for_sd(0.08, 200.0), flicker=0.02)
    result = calibrate_wheel(simulate(rig, sensor, SimClock(200.0), seconds=60.0, seed=2), radius=0.28)
    checks = result.quality["residual_checks"]
    assert checks["noise"] == "correlated"
    law = checks["low_frequency_noise"]
    assert len(law) == 3 and law[0]["beta"] == law[1]["beta"] > 0
    assert "1/f^" in result.quality["uncertainty"] and "two octaves" in result.quality["uncertainty"]
