"""Sine fits against known truth, the Cramér-Rao bound and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from accelrig.errors import DataError
from accelrig.estimation.sinefit import (
    fit_sine,
    interpolated_dft_frequency,
    rife_boorstyn_frequency_sd,
    sine_crb,
)

FS = 2048.0
N = 2048
T = np.arange(N) / FS


def slider_acceleration(t, f, radius=0.00635, rod=0.0353, phase=0.3):
    """Exact slider-crank acceleration (REFERENCES.md), written out independently of the rig."""
    w = 2 * np.pi * f
    p = w * t + phase
    s2 = np.sin(p) ** 2
    d = rod**2 - radius**2 * s2
    return w**2 * (-radius * np.cos(p) - radius**2 * (np.cos(2 * p) * d + radius**2 * s2 * np.cos(p) ** 2) / d**1.5)


def test_three_parameter_fit_is_exact_without_noise():
    y = 1.5 + 4.0 * np.cos(2 * np.pi * 5.2 * T + 1.0) + 0.7 * np.cos(2 * np.pi * 10.4 * T - 2.0)
    fit = fit_sine(T, y, frequency=5.2, harmonics=2, fit_frequency=False)
    assert fit.parameter_names == ["offset", "amplitude_1", "phase_1", "amplitude_2", "phase_2"]
    np.testing.assert_allclose(fit.amplitude, [4.0, 0.7], atol=1e-10)
    np.testing.assert_allclose(fit.phase, [1.0, -2.0], atol=1e-10)
    assert fit.offset == pytest.approx(1.5, abs=1e-10)
    assert fit.frequency_uncertainty == 0.0
    assert fit.covariance.shape == (5, 5)


@settings(max_examples=25, deadline=None)
@given(
    frequency=st.floats(1.0, 40.0),
    amplitude=st.floats(0.1, 50.0),
    phase=st.floats(-3.1, 3.1),
    offset=st.floats(-20.0, 20.0),
    t0=st.floats(0.0, 500.0),
)
def test_four_parameter_fit_recovers_a_clean_sine_anywhere(frequency, amplitude, phase, offset, t0):
    t = t0 + np.arange(1024) / 512.0
    y = offset + amplitude * np.cos(2 * np.pi * frequency * t + phase)
    fit = fit_sine(t, y)
    assert fit.converged
    assert fit.frequency == pytest.approx(frequency, rel=1e-8)
    assert fit.amplitude[0] == pytest.approx(amplitude, rel=1e-6)
    assert np.angle(np.exp(1j * (fit.phase[0] - phase))) == pytest.approx(0.0, abs=1e-5)
    assert fit.offset == pytest.approx(offset, abs=1e-6 * (1 + amplitude))


def test_frequency_sd_matches_crb_and_reported_uncertainty():
    """Monte Carlo: the estimator is efficient and its stated uncertainty is honest."""
    rng = np.random.default_rng(7)
    f, amp, sigma = 7.3, 10.0, 0.08
    bound = sine_crb(T, f, amp, 0.4, sigma)
    errors, stated = [], []
    for _ in range(150):
        y = 3.0 + amp * np.cos(2 * np.pi * f * T + 0.4) + sigma * rng.standard_normal(N)
        fit = fit_sine(T, y)
        errors.append(fit.frequency - f)
        stated.append(fit.frequency_uncertainty)
    errors = np.array(errors)
    # 150 draws: the sd of a sample sd is about 6 %
    assert 0.8 < errors.std() / bound.frequency_sd < 1.25
    assert abs(errors.mean()) < 4 * bound.frequency_sd / np.sqrt(errors.size)
    assert np.mean(stated) / bound.frequency_sd == pytest.approx(1.0, abs=0.05)


def test_exact_crb_agrees_with_rife_boorstyn():
    # many whole cycles: the closed form for one tone is exact up to O(1/N)
    bound = sine_crb(T, 100.0, 10.0, 0.0, 0.08)
    assert bound.frequency_sd == pytest.approx(1.38e-4, rel=0.01)  # REFERENCES.md example
    assert bound.frequency_sd == pytest.approx(rife_boorstyn_frequency_sd(10.0, 0.08, N, FS), rel=0.01)
    assert bound.amplitude_sd[0] == pytest.approx(np.sqrt(2 * 0.08**2 / N), rel=0.01)


def test_harmonics_remove_the_one_sine_bias_on_slider_crank_motion():
    rng = np.random.default_rng(3)
    f, sigma = 7.7, 0.08
    one, three = [], []
    for _ in range(30):
        y = slider_acceleration(T, f) + sigma * rng.standard_normal(N)
        one.append(fit_sine(T, y, harmonics=1).frequency - f)
        fit3 = fit_sine(T, y, harmonics=3)
        three.append(fit3.frequency - f)
    bound = sine_crb(T, f, fit3.amplitude, fit3.phase, sigma)
    assert abs(np.mean(one)) > 10 * bound.frequency_sd  # the one-sine fit is biased
    assert abs(np.mean(three)) < 1.0 * bound.frequency_sd
    # the second harmonic is about lambda times the first
    assert fit3.amplitude[1] / fit3.amplitude[0] == pytest.approx(0.00635 / 0.0353, rel=0.03)


def test_nonuniform_timestamps_are_used_not_assumed():
    rng = np.random.default_rng(11)
    t = np.sort(rng.uniform(0.0, 1.0, 2048))
    y = 2.0 * np.cos(2 * np.pi * 6.37 * t - 0.5) + 0.01 * rng.standard_normal(t.size)
    fit = fit_sine(t, y)
    assert fit.converged
    assert abs(fit.frequency - 6.37) < 4 * fit.frequency_uncertainty
    assert fit.frequency_uncertainty < 1e-3


def test_sample_index_fit_gives_cycles_per_sample():
    nu = 10.0 / 2047.3  # 10 Hz excitation at a true rate of 2047.3 Hz
    y = 5.0 * np.cos(2 * np.pi * nu * np.arange(N) + 0.2)
    fit = fit_sine(None, y)
    assert fit.frequency == pytest.approx(nu, rel=1e-10)
    fit_idx = fit_sine(np.arange(N), y)
    assert fit_idx.frequency == pytest.approx(fit.frequency, rel=1e-12)


@pytest.mark.parametrize("cycles", [2.5, 3.3, 7.75, 11.5])
def test_interpolated_dft_is_well_under_half_a_bin(cycles):
    rng = np.random.default_rng(int(cycles * 100))
    errors = []
    for fraction in np.linspace(0.0, 0.95, 12):
        f = cycles + fraction
        y = 1.0 + 10.0 * np.cos(2 * np.pi * f * T + rng.uniform(-np.pi, np.pi)) + 0.08 * rng.standard_normal(N)
        errors.append(interpolated_dft_frequency(T, y) - f)
    assert np.max(np.abs(errors)) < 0.1  # bin = 1 Hz here


def test_start_from_dft_converges_on_two_and_a_half_cycles():
    rng = np.random.default_rng(5)
    for _ in range(20):
        f = 2.5 + rng.uniform(0, 0.1)
        y = slider_acceleration(T, f, phase=rng.uniform(0, 2 * np.pi)) + 0.08 * rng.standard_normal(N)
        fit = fit_sine(T, y, harmonics=3)
        assert fit.converged
        assert abs(fit.frequency - f) < 5 * fit.frequency_uncertainty


def test_model_evaluates_the_fit():
    y = 0.5 + 3.0 * np.cos(2 * np.pi * 4.1 * T + 0.3)
    fit = fit_sine(T, y)
    np.testing.assert_allclose(fit.model(T), fit.fitted, atol=1e-9)
    assert fit.residual_sd < 1e-9


@pytest.mark.parametrize(
    "t, y, kwargs, message",
    [
        (T, np.cos(2 * np.pi * 1.0 * T), {}, "cycles"),  # 1 cycle
        (T[:10], np.cos(2 * np.pi * 300 * T[:10]), {}, "samples"),
        (T, np.where(np.arange(N) == 5, np.nan, np.cos(2 * np.pi * 5 * T)), {}, "NaN"),
        (T[:-1], np.cos(2 * np.pi * 5 * T), {}, "one time per sample"),
        (T, np.cos(2 * np.pi * 5 * T), {"fit_frequency": False}, "needs the frequency"),
        (T, np.cos(2 * np.pi * 5 * T), {"frequency": 600.0, "harmonics": 2}, "Nyquist"),
        (T[::-1], np.cos(2 * np.pi * 5 * T), {}, "increasing"),
    ],
)
def test_bad_input_says_what_is_wrong(t, y, kwargs, message):
    with pytest.raises(DataError, match=message):
        fit_sine(t, y, **kwargs)


def test_uniform_grid_shortcuts_equal_the_direct_basis():
    """On a uniform grid the basis's cos/sin come from block phasors and its Gram matrix in closed
    form: both must equal the direct computation, for any stride, harmonics and frequency."""
    from accelrig.estimation.sinefit import _basis, _uniform_gram, _uniform_step

    rng = np.random.default_rng(11)
    for _ in range(60):
        n, harmonics, stride = int(rng.integers(1100, 9000)), int(rng.integers(1, 5)), int(rng.integers(1, 4))
        tc = (np.arange(n, dtype=float) - (n - 1) / 2.0)[::stride]
        step = _uniform_step(tc)
        assert step == stride
        frequency = rng.uniform(0.01, 0.49 / harmonics) / step * rng.choice([1.0, 0.01])
        fast, _ = _basis(tc, frequency, harmonics, derivative=False, step=step)
        direct = np.column_stack([np.ones(tc.size)] + [f(2 * np.pi * k * frequency * tc)
                                                        for k in range(1, harmonics + 1) for f in (np.cos, np.sin)])
        np.testing.assert_allclose(fast, direct, atol=1e-11)
        np.testing.assert_allclose(_uniform_gram(tc, step, frequency, harmonics), direct.T @ direct,
                                   atol=1e-10 * tc.size)
    assert _uniform_step(np.array([0.0, 1.0, 2.0, 3.5])) is None


def test_uniform_and_general_paths_agree():
    """The same samples fitted on an exact grid (fast path) and on one with a tiny irregularity
    (general path) give the same frequency, amplitudes and uncertainties."""
    rng = np.random.default_rng(12)
    n = 20000
    k = np.arange(n, dtype=float)
    y = 3.0 + 500.0 * np.cos(2 * np.pi * 0.0031 * k + 0.4) + 40.0 * np.cos(4 * np.pi * 0.0031 * k - 1.0)
    y += rng.normal(0.0, 2.0, n)
    nudged = k.copy()
    nudged[-1] += 1e-9
    fast = fit_sine(k, y, frequency=0.00312, harmonics=3, check_noise=True)
    general = fit_sine(nudged, y, frequency=0.00312, harmonics=3, check_noise=True)
    assert abs(fast.frequency - general.frequency) < 1e-4 * fast.frequency_uncertainty
    np.testing.assert_allclose(fast.amplitude, general.amplitude, rtol=1e-9)
    np.testing.assert_allclose(fast.frequency_uncertainty, general.frequency_uncertainty, rtol=1e-6)
    assert abs(fast.frequency - 0.0031) < 4 * fast.frequency_uncertainty
