"""The shared residual check (accelrig.estimation.residuals) against processes whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from accelrig.errors import CalibrationError
from accelrig.estimation.residuals import (
    MIN_BLOCKS,
    MIN_HONEST_BLOCKS,
    FewBlocks,
    ar_sandwich_covariance,
    autocorrelation,
    block_scores,
    difference_noise_variance,
    lack_of_fit,
    sandwich_covariance,
    whiteness,
)
from accelrig.sim.sensor import SensorModel


def ar1(n, rho, rng):
    sensor = SensorModel(noise_density=SensorModel.noise_density_for_sd(1.0, 2.0), ar1=rho, range_g=16)
    return sensor.noise(n, rng, 2.0)[:, 0]


def test_white_noise_passes_and_ar1_is_caught_with_its_integrated_time():
    rng = np.random.default_rng(1)
    white = whiteness(rng.standard_normal(20000))
    assert not white.correlated and abs(white.tau - 1.0) < 0.15 and white.inflation < 1.1
    rho = 0.9
    check = whiteness(ar1(200000, rho, rng))
    assert check.correlated
    # tau of AR(1) = (1 + rho) / (1 - rho) = 19
    assert check.tau == pytest.approx((1 + rho) / (1 - rho), rel=0.15)
    assert "correlated" in check.describe()


def test_false_alarm_rate_of_the_whiteness_decision_is_small():
    rng = np.random.default_rng(2)
    alarms = sum(whiteness(rng.standard_normal(2000)).correlated for _ in range(300))
    assert alarms <= 6   # ALPHA = 1 %: 3 expected


def test_sandwich_covers_the_mean_of_correlated_noise_where_the_white_formula_does_not():
    rng = np.random.default_rng(3)
    n, rho = 20000, 0.9
    means, u_sandwich, u_white = [], [], []
    for _ in range(200):
        x = ar1(n, rho, rng)
        mean = x.mean()
        r = x - mean
        jac = np.ones((n, 1))
        check = whiteness(r)
        block = check.block_length()
        sw = sandwich_covariance(jac.T @ jac, block_scores(jac, r, block), block)
        assert not sw.underresolved
        means.append(mean)
        u_sandwich.append(np.sqrt(sw.covariance[0, 0]))
        u_white.append(r.std() / np.sqrt(n))
    sd = np.std(means)
    assert np.median(u_sandwich) / sd == pytest.approx(1.0, abs=0.2)
    assert np.median(u_white) / sd < 0.35          # 1/sqrt(19) = 0.23: the white u is far too small


def test_few_batch_means_blocks_take_students_t_and_too_few_are_refused():
    """A mean of AR(1) noise (tau 19) from 6 blocks of 5 tau: batch means' u at k = 2 covers about 88 %, Student's t
    on the 5 dof (k 2.65) about 95 %; fewer than MIN_HONEST_BLOCKS blocks are refused, naming the cause."""
    rng = np.random.default_rng(5)
    rho, tau = 0.9, 19.0
    block, blocks = int(5 * tau), 6
    n = block * blocks
    x = np.empty((4000, n))
    x[:, 0] = rng.standard_normal(4000)
    e = rng.standard_normal((4000, n)) * np.sqrt(1 - rho**2)
    for t in range(1, n):
        x[:, t] = rho * x[:, t - 1] + e[:, t]
    # u of each run's mean from the production sandwich: its residuals about the mean, in blocks
    ones = np.ones((n, 1))
    u = np.array([np.sqrt(sandwich_covariance(np.array([[float(n)]]), block_scores(ones, row - row.mean(), block),
                                              block).covariance[0, 0]) for row in x])
    z = np.abs(x.mean(axis=1)) / u
    few = FewBlocks(blocks, block, n, 0.01)
    assert few.few and not few.refused and few.dof == blocks - 1
    assert few.coverage_factor == pytest.approx(2.65, abs=0.01)
    assert np.mean(z <= 2.0) < 0.9
    assert 0.93 <= np.mean(z <= few.coverage_factor) <= 0.97
    assert "Student's t, k = 2.65" in few.describe()
    # enough blocks: k = 2 as before, nothing said
    assert FewBlocks(MIN_BLOCKS, block, MIN_BLOCKS * block).coverage_factor == 2.0
    assert FewBlocks(MIN_BLOCKS, block, MIN_BLOCKS * block).describe() == ""
    # too few: a refusal with the cause and how much longer to record
    short = FewBlocks(MIN_HONEST_BLOCKS - 2, 2000, 6000, 0.005)
    assert short.refused
    error = short.refusal("the gains")
    assert isinstance(error, CalibrationError)
    assert "wanders more slowly than the record can measure" in str(error) and "blocks of 10 s" in str(error)
    assert "record at least 2 times longer" in error.hint and "settle" in error.hint


def test_sandwich_reduces_to_the_usual_covariance_for_white_noise():
    rng = np.random.default_rng(4)
    n = 40000
    t = np.arange(n) / 100.0
    jac = np.column_stack([np.sin(2 * np.pi * 1.3 * t), np.cos(2 * np.pi * 1.3 * t), np.ones(n)])
    r = rng.standard_normal(n) * 0.5
    sw = sandwich_covariance(jac.T @ jac, block_scores(jac, r, 200), 200)
    usual = 0.25 * np.linalg.inv(jac.T @ jac)
    assert np.sqrt(np.diag(sw.covariance)) == pytest.approx(np.sqrt(np.diag(usual)), rel=0.3)


def test_block_scores_keep_instants_whole_and_lose_no_row():
    jac = np.arange(30, dtype=float).reshape(15, 2)
    r = np.ones(15)
    sums = block_scores(jac, r, block=3, rows_per_instant=3)    # 5 instants: blocks of 3 and 2
    assert sums.shape == (2, 2)
    assert sums.sum(axis=0) == pytest.approx(jac.sum(axis=0))


def test_lack_of_fit_against_the_difference_noise_estimate():
    rng = np.random.default_rng(5)
    t = np.linspace(0, 10, 5000)
    signal = np.sin(t) * 3
    y = signal + rng.standard_normal(t.size) * 0.1
    var, dof = difference_noise_variance(y)
    assert var == pytest.approx(0.01, rel=0.1) and dof < t.size
    fit_ok = lack_of_fit(np.var(y - signal), t.size - 1, var, dof)
    assert not fit_ok.significant()
    wrong = lack_of_fit(np.var(y - 0.98 * signal), t.size - 1, var, dof)    # 2 % gain error
    assert wrong.significant() and wrong.ratio > 1.1 and "does not fit" in wrong.describe()


def test_a_short_last_block_joins_the_previous_one():
    sums = block_scores(np.ones((7, 1)), np.ones(7), block=3)    # 3 + 4: the 1 left over is merged
    assert sums.ravel().tolist() == [3.0, 4.0]


def test_coloured_sim_noise_is_continuous_across_blocks():
    """One process, whatever the block cut: AR(1) lag-1 correlation survives block joins."""
    sensor = SensorModel(noise_density=SensorModel.noise_density_for_sd(1.0, 100.0), ar1=0.95, range_g=16)
    rng = np.random.default_rng(6)
    x = np.concatenate([sensor.noise(7, rng, 100.0)[:, 0] for _ in range(4000)])
    joins = np.arange(7, x.size, 7)
    assert np.corrcoef(x[joins - 1], x[joins])[0, 1] > 0.9


def _sine_fit_design(n: int, cycles_per_sample: float, harmonics: int) -> np.ndarray:
    """Columns of a sine fit with harmonics and a free frequency (the slider-crank step's shape)."""
    t = np.arange(n) - (n - 1) / 2
    w = 2 * np.pi * cycles_per_sample
    cols = [np.ones(n), -t * np.sin(w * t)]
    for k in range(1, harmonics + 1):
        cols += [np.cos(k * w * t), np.sin(k * w * t)]
    return np.column_stack(cols)


def test_the_ar_sandwich_gives_back_what_the_fit_took_out_of_the_noise():
    # A 1-s step at 6 Hz, 2048 samples, AR(1) rho 0.9: the fit's columns live where the noise is strong,
    # so the residuals are poorer there than the noise.  Measured without the correction: u 0.90 of the
    # exact (J+ Sigma J+') one; with it 0.99.
    n, rho = 2048, 0.9
    jac = _sine_fit_design(n, 6 / 2048, 4)
    normal = jac.T @ jac
    bread = np.linalg.inv(normal)
    lags = rho ** np.abs(np.arange(n)[:, None] - np.arange(n)[None, :])
    exact = np.sqrt(np.diag(bread @ jac.T @ lags @ jac @ bread))
    rng = np.random.default_rng(11)
    ratios = []
    for _ in range(40):
        e = ar1(n, rho, rng)
        resid = e - jac @ (bread @ (jac.T @ e))
        cov = ar_sandwich_covariance(normal, jac, resid).covariance
        ratios.append(np.sqrt(np.diag(cov)) / exact)
    mean = np.mean(ratios, axis=0)
    assert np.all((mean > 0.95) & (mean < 1.05)), mean


def test_blockwise_autocorrelation_equals_the_direct_sums(monkeypatch):
    # blocks shorter than the lags asked for, and a short last block: every pair x_i x_(i+k) counted once
    from accelrig.estimation import residuals

    rng = np.random.default_rng(11)
    x = np.cumsum(rng.standard_normal(203)) * 0.1 + rng.standard_normal(203)
    centred = x - x.mean()
    direct = np.array([centred[: x.size - k] @ centred[k:] for k in range(150)]) / (centred @ centred)
    monkeypatch.setattr(residuals, "AUTOCORRELATION_BLOCK", 17)
    assert np.allclose(autocorrelation(x, 149), direct, atol=1e-12)
    monkeypatch.setattr(residuals, "AUTOCORRELATION_BLOCK", 1000)
    assert np.allclose(autocorrelation(x, 149), direct, atol=1e-12)


def test_whiteness_reads_tau_from_the_first_lags_only_when_the_window_is_there(monkeypatch):
    # a long memory (rho 0.999, tau ~ 2000) needs lags beyond the first few thousand: the doubling finds them
    from accelrig.estimation import residuals

    rng = np.random.default_rng(12)
    e = rng.standard_normal(60000)
    x = np.empty_like(e)
    x[0] = e[0]
    for i in range(1, e.size):
        x[i] = 0.999 * x[i - 1] + e[i]
    full = residuals.integrated_time(autocorrelation(x, x.size // 4))
    monkeypatch.setattr(residuals, "SOKAL_FIRST_LAGS", 64)
    w = whiteness(x)
    assert (w.tau, w.window) == pytest.approx(full)
    assert w.window > 64


def test_pooled_noise_of_white_residuals_is_flat_at_the_noise_level_and_no_fit_stands_out():
    from accelrig.estimation.residuals import pooled_noise_model

    rng = np.random.default_rng(3)
    n, sd = 1024, 0.5
    t = np.arange(n)
    fits = []
    for cycles in (0.004, 0.01, 0.03):   # sine fits at three frequencies, as a slider-crank's steps
        jac = np.column_stack([np.cos(2 * np.pi * cycles * t), np.sin(2 * np.pi * cycles * t)])
        y = jac @ [1.0, 2.0] + rng.normal(0, sd, n)
        coef = np.linalg.lstsq(np.column_stack([np.ones(n), jac]), y, rcond=None)[0]
        fits.append((jac, y - np.column_stack([np.ones(n), jac]) @ coef))
    model = pooled_noise_model(fits)
    omega = 2 * np.pi * np.linspace(0.0, 0.5, 400)
    # over the whole band the levels average to the noise variance (white: sd^2 per sample everywhere)
    assert np.mean(model.noise.spectrum(omega)) == pytest.approx(sd**2, rel=0.05)
    assert model.noise.seen.all() and model.pooled.all() and not model.stands_out.any()
    assert np.allclose(model.levels, 1.0, atol=0.1)
    # a fit with twice the noise stands out, is left out of the pool, and keeps its own level
    jac = fits[1][0]
    noisy = rng.normal(0, 2 * sd, n)
    noisy -= np.column_stack([np.ones(n), jac]) @ np.linalg.lstsq(np.column_stack([np.ones(n), jac]), noisy,
                                                                rcond=None)[0]
    model = pooled_noise_model([fits[0], (jac, noisy), fits[2]])
    assert list(model.stands_out) == [False, True, False] and list(model.pooled) == [True, False, True]
    assert model.levels[1] == pytest.approx(4.0, rel=0.15)


def test_coverage_factor_is_students_t_at_the_probability_of_k_2():
    # GUM Table G.2 (p = 95.45 %): 13.97 at 1 dof, 2.28 at 10, 2.05 at 50, 2.00 at infinity
    from accelrig.estimation.gum import coverage_factor

    assert [round(coverage_factor(nu), 2) for nu in (1, 10, 50)] == [13.97, 2.28, 2.05]
    assert coverage_factor(float("inf")) == pytest.approx(2.0, abs=1e-5)
    with pytest.raises(ValueError):
        coverage_factor(0.0)


def test_a_variance_from_pooled_bands_states_the_dof_it_scatters_with():
    # a sine fit's amplitude variance read from the bands of three short fits (white noise): the bands rest on a
    # few periodogram ordinates each, so the variance scatters like a chi-square of about ten dof, not of n - p
    from accelrig.estimation.residuals import ar_sandwich_covariance, band_variance_shares, pooled_noise_model

    rng = np.random.default_rng(5)
    n = 256
    t = np.arange(n)
    columns = [np.column_stack([np.cos(2 * np.pi * c * t), np.sin(2 * np.pi * c * t)]) for c in (0.02, 0.05, 0.12)]
    jac = columns[0]
    row = np.linalg.inv(jac.T @ jac)[0]          # g' (J'J)^-1 for the cosine amplitude
    values, dofs = [], []
    for rep in range(150):
        fits = []
        for c in columns:
            design = np.column_stack([np.ones(n), c])
            y = rng.normal(0, 1, n)
            fits.append((c, y - design @ np.linalg.lstsq(design, y, rcond=None)[0]))
        model = pooled_noise_model(fits)
        shares = band_variance_shares(jac, row[None, :], model.noise.edges)[0]
        value = model.levels[0] * shares @ model.noise.levels
        if rep == 0:   # the shares are the sandwich's own sum, split by band
            cov = ar_sandwich_covariance(jac.T @ jac, jac, fits[0][1], noise=model.for_fit(0)).covariance
            assert value == pytest.approx(cov[0, 0], rel=1e-9)
        values.append(value)
        dofs.append(model.variance_dof(0, shares))
    values = np.array(values)
    assert np.mean(values) == pytest.approx(np.linalg.inv(jac.T @ jac)[0, 0], rel=0.1)   # unbiased
    empirical = 2 * np.mean(values) ** 2 / np.var(values)
    assert 6 < empirical < 16                      # far below n - p = 253: the bands' scatter is real
    assert 0.75 < np.median(dofs) / empirical < 1.25
