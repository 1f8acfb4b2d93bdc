"""Does the model fit, and is the noise white?  The one residual check every estimator uses.

Every fit in accelrig states u from a covariance that assumes the residuals are
white noise around a model that is true.  Two things break that on real rigs:

* **Correlated noise** (AR-like, 1/f, a slow wander).  The estimates stay
  unbiased but their sd grows: for a mean of n samples with integrated
  autocorrelation time tau (in samples) the variance is tau times the white
  value.  ``whiteness`` measures tau from the residuals (Sokal's automatic
  window) and tests the autocorrelations against white (Ljung-Box).

* **Lack of fit** (a wheel that stops, an imbalance, a wandering motor,
  drift).  The residual variance then exceeds what the sensor's noise alone
  gives.  ``lack_of_fit`` compares the two with an F test, the noise measured
  without the model (``difference_noise_variance``, or a procedure's own
  model-free estimate such as the scatter within a still pose).

When the residuals are correlated, ``sandwich_covariance`` gives the
covariance of a least-squares estimate that stays honest: the sandwich
(J'J)^-1 M (J'J)^-1 whose middle M is estimated by batch means of the
score J_t' r_t over blocks much longer than the correlation time (a
non-overlapping-blocks HAC estimator).  It was chosen over scaling u by
sqrt(tau) because it is right for every parameter, not only for means: a
sine fit's amplitude sees the noise near its frequency, which tau (the noise
at frequency 0) does not describe.  ``block_scores`` makes the block sums
from an in-memory Jacobian; a chunked fit can sum its own blocks.  Noise slower than the longest
blocks a record allows (1/f-like) is seen as flat by batch means; ``fit_power_law`` fits the residuals'
lowest octaves as white + c f^-beta and ``low_frequency_covariance`` adds the part batch means miss.

The policy (the same for every procedure):

* residuals pass as white unless the Ljung-Box test rejects at ``ALPHA`` and
  the correlation would grow u by more than ``MATERIAL_INFLATION``;
* correlated residuals: u from the sandwich, and the result says so;
* lack of fit: warn with the ratio and what it means; refuse beyond the
  procedure's own stated limit (each procedure states it, since what a
  5 % excess means differs between a still pose and a spinning wheel).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.fft import next_fast_len as _next_fast_len

from accelrig.estimation import distributions as _sps

ALPHA = 0.01                 # false alarm rate of each test
MATERIAL_INFLATION = 1.1     # u growing by less than 10 % is not worth a change of method
SOKAL_WINDOW = 5.0           # window M >= c tau (Sokal 1997): bias of tau below e^-c
MIN_BLOCKS = 20              # batch means need this many blocks for a usable middle matrix
# Fewer than MIN_BLOCKS blocks: u is still the batch means', but its expanded form takes Student's t on their K - 1
# degrees of freedom (``FewBlocks``); fewer than MIN_HONEST_BLOCKS: refused (``FewBlocks.refusal``, argued there).
MIN_HONEST_BLOCKS = 5
BLOCK_PER_TAU = 20           # block length in units of tau: the batch-means bias ~ tau / block
SOKAL_FIRST_LAGS = 4096      # lags first computed for tau (more only while Sokal's window is not reached)


# Series longer than this are correlated block by block: the memory then grows with the lags asked
# for, not with the series (a block and the max_lag samples after it at a time).
AUTOCORRELATION_BLOCK = 65536


def autocorrelation(x: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation rho_0..rho_max_lag of a 1-D series, mean removed (FFT, O(n log n)).

    A long series is summed block by block (each block against itself and the max_lag samples
    after it), so the working memory is O(block + max_lag) and no mean-removed copy of the whole
    series is made; the sums are the same as those of one transform of the whole series."""
    x = np.asarray(x, dtype=float)
    x = x.ravel() if x.ndim != 1 else x
    n = x.size
    max_lag = int(min(max_lag, n - 1))
    mean = float(np.mean(x))
    acov = np.zeros(max_lag + 1)
    for lo in range(0, n, AUTOCORRELATION_BLOCK):
        block = x[lo:lo + AUTOCORRELATION_BLOCK] - mean
        after = x[lo:lo + AUTOCORRELATION_BLOCK + max_lag] - mean
        # the lags -block.size .. -1 wrap round to the top of the transform: block.size + max_lag + 1
        # points (and room for the whole correlation) keep them off every lag asked for
        size = _next_fast_len(block.size + max(after.size, max_lag + 1))
        spectrum = np.conj(np.fft.rfft(block, size))
        spectrum *= np.fft.rfft(after, size)
        acov += np.fft.irfft(spectrum, size)[: max_lag + 1]
    if acov[0] <= 0:
        return np.concatenate([[1.0], np.zeros(max_lag)])
    return acov / acov[0]


def integrated_time(rho: np.ndarray) -> tuple[float, int]:
    """Integrated autocorrelation time tau = 1 + 2 sum rho_k over Sokal's window, and the window.

    The window is the smallest M with M >= SOKAL_WINDOW * tau(M); when no lag
    qualifies, the last one available.  White noise gives tau ~ 1; tau < 1
    (anti-correlated residuals) is returned as measured.
    """
    rho = np.asarray(rho, dtype=float)
    taus = 1.0 + 2.0 * np.cumsum(rho[1:])
    lags = np.arange(1, rho.size)
    ok = lags >= SOKAL_WINDOW * taus
    window = int(lags[np.argmax(ok)]) if ok.any() else int(lags[-1])
    return float(taus[window - 1]), window


@dataclass
class Whiteness:
    """What the residuals' autocorrelation says about the noise."""

    n: int
    lag1: float            # rho_1
    tau: float             # integrated autocorrelation time, samples
    window: int            # Sokal window used for tau
    q: float               # Ljung-Box statistic over ``lags``
    lags: int
    p_value: float
    # Sokal's window was reached within the lags the series allows, so tau is measured.  When it was not, the
    # correlation still runs at the last lag and tau is only a lower bound: the noise wanders more slowly than the
    # series can show (``FewBlocks`` says what that costs a batch-means u)
    resolved: bool = True

    @property
    def inflation(self) -> float:
        """Factor on the u of a mean computed as if white: sqrt(tau), never below 1."""
        return float(np.sqrt(max(self.tau, 1.0)))

    @property
    def correlated(self) -> bool:
        return self.p_value < ALPHA and self.inflation > MATERIAL_INFLATION

    def block_length(self) -> int:
        """Batch-means block length for ``sandwich_covariance``, samples."""
        return max(1, int(np.ceil(BLOCK_PER_TAU * max(self.tau, 1.0))))

    def describe(self) -> str:
        return (f"residuals are correlated in time (lag-1 autocorrelation {self.lag1:.2f}, "
                f"integrated time {self.tau:.1f} samples): a white-noise u would be "
                f"{self.inflation:.1f}x too small")

    def to_dict(self) -> dict:
        return {"n": self.n, "lag1": self.lag1, "tau_samples": self.tau, "window": self.window,
                "ljung_box_q": self.q, "lags": self.lags, "p_value": self.p_value,
                "inflation": self.inflation, "correlated": self.correlated, "resolved": self.resolved}


def whiteness(residuals: np.ndarray, lags: int | None = None) -> Whiteness:
    """Test a 1-D residual series (in time order) for whiteness and measure its correlation time.

    ``lags`` for Ljung-Box defaults to min(20, n/5) (Box-Jenkins' usual choice);
    tau is computed with up to n/4 lags.
    """
    r = np.asarray(residuals, dtype=float)
    r = r.ravel() if r.ndim != 1 else r      # a column of an (n, k) array is used in place, not copied
    n = r.size
    if n < 10:
        raise ValueError(f"a whiteness test needs at least 10 residuals, got {n}")
    lags = int(lags or max(1, min(20, n // 5)))
    # Sokal's window is looked for over up to n/4 lags; the lags are doubled from a few thousand only
    # while no window qualifies (noise with a long memory), so a short correlation costs no O(n) lags
    max_lag = max(lags, n // 4)
    reach = min(max_lag, max(lags, SOKAL_FIRST_LAGS))
    while True:
        rho = autocorrelation(r, reach)
        tau, window = integrated_time(rho)
        if window >= SOKAL_WINDOW * tau or reach >= max_lag:
            break
        reach = min(2 * reach, max_lag)
    k = np.arange(1, lags + 1)
    q = float(n * (n + 2) * np.sum(rho[1: lags + 1] ** 2 / (n - k)))
    p = float(_sps.chi2.sf(q, lags))
    return Whiteness(n, float(rho[1]), tau, window, q, lags, p, window >= SOKAL_WINDOW * tau)


def whiteness_by_column(residuals: np.ndarray) -> list[Whiteness]:
    """``whiteness`` of each column of an (n, k) residual array (one per axis)."""
    residuals = np.asarray(residuals, dtype=float)
    return [whiteness(residuals[:, j]) for j in range(residuals.shape[1])]


def block_scores(jacobian: np.ndarray, residuals: np.ndarray, block: int, rows_per_instant: int = 1) -> np.ndarray:
    """Sums of the score J_t' r_t over consecutive blocks of ``block`` instants, (K, p).

    Rows of ``jacobian`` (n_rows, p) and ``residuals`` (n_rows,) are in time
    order with the ``rows_per_instant`` rows of one instant (e.g. three axes)
    adjacent, so a block never splits an instant.  A last partial block is
    kept when it is at least half a block long, else merged into the previous.
    """
    jacobian = np.asarray(jacobian, dtype=float)
    residuals = np.asarray(residuals, dtype=float).ravel()
    scores = jacobian * residuals[:, None]
    instants = residuals.size // rows_per_instant
    scores = scores[: instants * rows_per_instant].reshape(instants, rows_per_instant, -1).sum(axis=1)
    k = max(1, instants // block)
    if instants - k * block >= block / 2:
        k += 1
    edges = np.minimum(np.arange(k + 1) * block, instants)
    edges[-1] = instants
    return np.add.reduceat(scores, edges[:-1], axis=0)


@dataclass
class Sandwich:
    covariance: np.ndarray
    blocks: int
    block: int             # instants per block
    method: str = "batch-means sandwich"
    # degrees of freedom of the middle matrix's estimate (GUM G.4: the t factor of an expanded u): batch means
    # over K blocks have K - 1; an AR(p) spectrum fitted to n samples about n / p (Berk 1974: var S^ ~ 2p/n S^2)
    dof: float = float("inf")

    @property
    def underresolved(self) -> bool:
        """Too few blocks for a trustworthy middle matrix (say so, widen or refuse)."""
        return self.blocks < MIN_BLOCKS

    def to_dict(self) -> dict:
        return {"method": self.method, "blocks": self.blocks, "block_samples": self.block,
                "underresolved": self.underresolved}


@dataclass
class FewBlocks:
    """What a batch-means u over ``blocks`` blocks of ``block`` samples (of an ``n``-sample record, ``period`` s
    per sample) can claim: the coverage factor of its expanded form, or a refusal.

    **Student's t.**  The middle matrix is a sum of K outer products of block sums: with independent blocks a
    Wishart with K - 1 degrees of freedom, so a parameter's u^2 is sigma^2 chi^2_(K-1) / (K - 1) and the
    interval that covers 95.45 % is +-t(K - 1) u (GUM G.3-G.4): 13.97 at K = 2, 4.53 at 3, 3.31 at 4, 2.87
    at 5, 2.32 at 10, 2.14 at 20.  From MIN_BLOCKS up k stays 2 (the doubling ladder keeps the widest of
    several block lengths, which errs wide by more than t adds).

    **Why not below MIN_HONEST_BLOCKS = 5.**  t presumes independent blocks; adjacent ones are not.  Their sums
    share the correlated pairs across their boundary: for a block b long against an integrated time tau they
    correlate by about r = tau / (4 b), which leaves the batch-means variance short by about 2 r.  And tau is
    itself read from the residuals of the record: with the mean removed and Sokal's window M ~ 5 tau, it
    reads low by about 2 M / n.  Blocks of 5 tau-hat (the ladder's shortest) in K = n / b of them are then
    about 5 (1 - 2 / K) tau long: 3 tau at K = 5 (r ~ 8 %: u some 8 % short, under a t of 2.87), 2.5 tau at
    K = 4 and 1.7 tau at K = 3 (u 15-25 % short on top of a t of 3.3-4.5 resting on 2-3 dof), and at K = 2
    no longer than the noise's own memory: the block sums then differ by little more than the fit removed,
    and u can be any size (held-out wheel, AR(1) 0.999 and a dominating random walk: errors of 26 u and of
    40,000 u with 2 blocks).  Below five blocks the record cannot say how large the noise's slow part is, so
    no u is stated.  Measured at the limit (wheel, stress simulator, AR(1) 0.995 and 0.997, 105 runs): 91 kept
    with 5-19 blocks, 6 of them with estimates beyond k u (3.3-5.7 u, every estimate of the run together:
    one noise moves them all), 14 refused."""

    blocks: int
    block: int
    n: int
    period: float = 0.0

    @property
    def dof(self) -> float:
        return float(max(self.blocks - 1, 1))

    @property
    def few(self) -> bool:
        return self.blocks < MIN_BLOCKS

    @property
    def refused(self) -> bool:
        return self.blocks < MIN_HONEST_BLOCKS

    @property
    def coverage_factor(self) -> float:
        from accelrig.estimation.gum import coverage_factor

        return coverage_factor(self.dof) if self.few else 2.0

    def describe(self) -> str:
        """One clause for the uncertainty line (empty when the blocks are enough for k = 2)."""
        if not self.few:
            return ""
        return (f"the batch means rest on {self.blocks} blocks ({self.blocks - 1} degrees of freedom), too few for "
                f"k = 2: the expanded uncertainty takes Student's t, k = {self.coverage_factor:.2f} (95.45 %)")

    def to_dict(self) -> dict:
        return {"blocks": self.blocks, "block_samples": self.block, "dof": self.dof,
                "coverage_factor": self.coverage_factor, "min_blocks_for_k2": MIN_BLOCKS,
                "min_blocks": MIN_HONEST_BLOCKS}

    def refusal(self, what: str = "the estimates"):
        """The error to raise when ``refused``: the cause and how much longer a record would do."""
        from accelrig.errors import CalibrationError

        longer = int(np.ceil(MIN_HONEST_BLOCKS * self.block / max(self.n, 1)))
        memory = (f"{self.block * self.period:.3g} s" if self.period > 0 else f"{self.block} samples")
        return CalibrationError(
            f"the noise wanders more slowly than the record can measure: its correlation asks for batch-means "
            f"blocks of {memory} and the record holds {self.blocks} of them (at least {MIN_HONEST_BLOCKS} are needed "
            f"to state a u for {what}; with fewer, the blocks are no longer than the noise's memory and u could be "
            "any size)",
            f"record at least {max(longer, 2)} times longer, or let the sensor settle at a steady temperature "
            "(powered, still) before calibrating")


def sandwich_covariance(normal_matrix: np.ndarray, scores: np.ndarray, block: int) -> Sandwich:
    """Covariance (J'J)^-1 M (J'J)^-1 with M = sum over blocks of S_b S_b' (batch means).

    ``normal_matrix`` is J'J of the (weighted) fit; ``scores`` the per-block
    score sums from ``block_scores`` (or a chunked fit's own).  The score sums
    are centred (at the least-squares optimum they sum to zero; removing their
    mean keeps a fit stopped short of it from inflating M).  With white noise
    M ~ sigma^2 J'J and this reduces to the usual sigma^2 (J'J)^-1.
    """
    scores = np.asarray(scores, dtype=float)
    k = scores.shape[0]
    centred = scores - scores.mean(axis=0)
    middle = centred.T @ centred * (k / max(k - 1, 1))
    bread = np.linalg.pinv(np.asarray(normal_matrix, dtype=float))
    cov = bread @ middle @ bread
    return Sandwich(0.5 * (cov + cov.T), k, int(block), dof=float(max(k - 1, 1)))


@dataclass
class LackOfFit:
    """Residual variance against a model-free noise variance (F test)."""

    residual_variance: float
    noise_variance: float
    dof_residual: float
    dof_noise: float
    p_value: float

    @property
    def ratio(self) -> float:
        """Residual rms over the noise sd (1 when the model explains everything but noise)."""
        return float(np.sqrt(self.residual_variance / self.noise_variance)) if self.noise_variance > 0 else np.inf

    def significant(self, alpha: float = ALPHA) -> bool:
        return self.p_value < alpha

    def describe(self) -> str:
        return (f"the model does not fit: residual rms is {self.ratio:.2f}x the sensor noise "
                f"measured without the model (F test p = {self.p_value:.1g})")

    def to_dict(self) -> dict:
        return {"residual_variance": self.residual_variance, "noise_variance": self.noise_variance,
                "rms_ratio": self.ratio, "dof_residual": self.dof_residual, "dof_noise": self.dof_noise,
                "p_value": self.p_value, "significant": self.significant()}


def lack_of_fit(residual_variance: float, dof_residual: float, noise_variance: float, dof_noise: float) -> LackOfFit:
    """F test of residual_variance (dof_residual) against noise_variance (dof_noise), one-sided."""
    if noise_variance <= 0:
        p = 0.0 if residual_variance > 0 else 1.0
    else:
        p = float(_sps.f.sf(residual_variance / noise_variance, dof_residual, dof_noise))
    return LackOfFit(float(residual_variance), float(noise_variance), float(dof_residual), float(dof_noise), p)


def difference_noise_variance(x: np.ndarray, order: int = 2) -> tuple[float, float]:
    """White-noise variance of a smooth signal plus noise, with no model: var of its
    ``order``-th differences over C(2 order, order), and its effective dof.

    A smooth signal sampled fast is nearly a polynomial over order + 1 samples,
    so its differences are noise alone.  The dof accounts for the overlap of
    successive differences (about n / (1 + 2 sum of their squared correlations)).
    Correlated noise makes this smaller than the true variance: a fit whose
    residuals are correlated will fail the lack-of-fit test against it, which is
    why the whiteness check runs first.
    """
    from math import comb

    x = np.asarray(x, dtype=float).ravel()
    d = np.diff(x, n=order)
    scale = comb(2 * order, order)
    # correlation of successive order-th differences of white noise: binomial convolution
    w = np.array([(-1) ** k * comb(order, k) for k in range(order + 1)], dtype=float)
    acf = np.correlate(w, w, mode="full")[order:] / scale
    dof = d.size / (1.0 + 2.0 * float(np.sum(acf[1:] ** 2)))
    return float(np.mean(d**2) / scale), dof


def pooled_whiteness(segments: list[np.ndarray]) -> Whiteness:
    """``whiteness`` of one noise process seen in several separate stretches (e.g. the still poses of a
    static run, one axis), each with its own mean removed.

    The autocovariances of the stretches are summed (each stretch long-weighted as it is) before tau is
    read, so a run of short poses gives one tau with the variance of the whole run's samples; the
    Ljung-Box statistics add (independent stretches), with their lags.  Removing each stretch's mean
    lowers every sample autocorrelation by about tau / n (the variance of that mean), which summed over
    Sokal's window M biases tau low by 2 M tau / n: at n = 800 samples and tau = 19 a quarter.  tau is
    corrected for it (divided by 1 - 2 M / n_eff, n_eff the stretches' sample-weighted mean length).
    """
    segments = [np.asarray(s, dtype=float).ravel() for s in segments]
    segments = [s for s in segments if s.size >= 10]
    if not segments:
        raise ValueError("a whiteness test needs a stretch of at least 10 residuals")
    n_total = int(sum(s.size for s in segments))
    max_lag = max(1, min(s.size for s in segments) // 4)
    acov = np.zeros(max_lag + 1)
    q, lags_total = 0.0, 0
    for s in segments:
        rho = autocorrelation(s, max_lag)
        var = float(np.var(s))
        acov[: rho.size] += rho * var * s.size
        lags = max(1, min(20, s.size // 5))
        k = np.arange(1, lags + 1)
        q += float(s.size * (s.size + 2) * np.sum(rho[1: lags + 1] ** 2 / (s.size - k)))
        lags_total += lags
    rho = acov / acov[0] if acov[0] > 0 else np.concatenate([[1.0], np.zeros(max_lag)])
    tau, window = integrated_time(rho)
    resolved = window >= SOKAL_WINDOW * tau
    n_eff = sum(s.size**2 for s in segments) / n_total
    shrink = 1.0 - 2.0 * window / n_eff
    if shrink > 0.25:
        tau /= shrink
    p = float(_sps.chi2.sf(q, lags_total))
    return Whiteness(n_total, float(rho[1]), float(tau), window, q, lags_total, p, resolved)


def pooled_variogram(segments: list[np.ndarray], lags: np.ndarray) -> np.ndarray:
    """Semivariogram V(k) = E[(x_t+k - x_t)^2] / 2 of one noise process seen in separate stretches (one axis
    of a static run's still poses), pooled over every pair k samples apart within a stretch.

    Beside ``pooled_whiteness`` for noise slower than the stretches: differences need no mean removed, so
    a memory as long as a stretch does not bias V (each stretch's own mean removed biases every sample
    autocorrelation low by about tau / n, which at tau ~ n is the whole of it), and V keeps rising for a
    noise without a level (a random walk), where the autocovariance does not exist."""
    segments = [np.asarray(s, dtype=float).ravel() for s in segments]
    out = np.empty(len(lags))
    for j, k in enumerate(np.asarray(lags, dtype=int)):
        pairs = [s[k:] - s[:-k] for s in segments if s.size > k]
        count = sum(d.size for d in pairs)
        if k < 1 or count == 0:
            raise ValueError(f"no pair of samples {k} apart within a stretch")
        out[j] = sum(float(d @ d) for d in pairs) / count / 2.0
    return out


# ---------------------------------------------------------------- short records: a parametric middle matrix

AR_MAX_ORDER = 20            # highest autoregressive order tried for the residual spectrum


@dataclass
class ARNoise:
    """An autoregressive model of the residuals: x_t = sum_k a_k x_{t-k} + e_t, var(e) = innovation."""

    coefficients: np.ndarray
    innovation: float

    @property
    def order(self) -> int:
        return int(self.coefficients.size)

    @property
    def label(self) -> str:
        return f"AR({self.order})"

    def spectrum(self, omega: np.ndarray) -> np.ndarray:
        """Two-sided spectral density per sample at angular frequencies omega (rad per sample);
        white noise of variance s2 gives s2 everywhere."""
        z = np.exp(-1j * np.asarray(omega, dtype=float))
        # 1 - sum_k a_k z^k = 1 - z (a_1 + a_2 z + ...), by Horner (polyval): no (n, order) matrix
        transfer = 1.0 - z * np.polyval(self.coefficients[::-1], z) if self.order else np.ones_like(z)
        return self.innovation / np.abs(transfer) ** 2

    def variance_ratio(self, cycles_per_sample: float) -> float:
        """S(f) over the marginal variance: the factor on a white-noise variance for a parameter that sees
        the noise at f (a sine's amplitude and phase); tau for f = 0."""
        omega = np.linspace(0.0, np.pi, 4097)
        marginal = float(np.mean(self.spectrum(omega)))   # the variance: the mean of S over a uniform grid
        return float(self.spectrum(np.array([2 * np.pi * cycles_per_sample]))[0] / marginal)


def _levinson_aic(acov: np.ndarray, n: int, max_order: int) -> ARNoise:
    """AR model from autocovariances acov[0..max_order] of n samples: Levinson-Durbin, order by AIC."""
    var = float(acov[0])
    best = (n * np.log(var), np.zeros(0), var)
    a = np.zeros(0)
    error = var
    for p in range(1, max_order + 1):
        reflection = (acov[p] - a @ acov[p - 1:0:-1]) / error if p > 1 else acov[1] / error
        a = np.concatenate([a - reflection * a[::-1], [reflection]])
        error *= 1.0 - reflection**2
        if error <= 0:
            break
        aic = n * np.log(error) + 2 * p
        if aic < best[0]:
            best = (aic, a.copy(), error)
    return ARNoise(best[1], float(best[2]))


def _projection_shortfall(noise: ARNoise, basis: np.ndarray, max_lag: int) -> np.ndarray:
    """What projecting noise of spectrum ``noise`` off the orthonormal columns ``basis`` (n, p) takes out of its
    autocovariance, lags 0..max_lag (the biased, 1/n estimate): E[e_t e_t+k - r_t r_t+k] summed over t, / n.

    r = (I - H) e with H = Q Q', so E[r r'] = Sigma - H Sigma - Sigma H + H Sigma H.  Sigma Q is a Toeplitz
    product, done as a circular convolution on 2n or more points (the AR spectrum sampled there).
    """
    n = basis.shape[0]
    size = 1 << int(np.ceil(np.log2(2 * n)))
    spectrum = noise.spectrum(2 * np.pi * np.arange(size // 2 + 1) / size)
    sigma_q = np.fft.irfft(spectrum[:, None] * np.fft.rfft(basis, size, axis=0), size, axis=0)[:n]
    q_c = basis @ (basis.T @ sigma_q)
    shortfall = np.empty(max_lag + 1)
    for k in range(max_lag + 1):
        shortfall[k] = (np.sum(basis[: n - k] * sigma_q[k:]) + np.sum(sigma_q[: n - k] * basis[k:])
                        - np.sum(q_c[: n - k] * basis[k:]))
    return shortfall / n


def ar_noise_model(residuals: np.ndarray, max_order: int = AR_MAX_ORDER, jacobian: np.ndarray | None = None) -> ARNoise:
    """AR model of a residual series: Levinson-Durbin on its autocovariance, order by AIC (<= max_order).

    With ``jacobian`` (the fit's, rows in time order, one instant each), the autocovariance is first
    corrected for what the fit took out of the noise.  Residuals are the noise with its projection on
    the fit's columns removed, and that projection is largest where the columns live: for a sine fit
    in coloured noise, at the sine's frequency, the very part of the spectrum that sets the sine's u.
    Left alone, a 1-s slider-crank step under AR(1) noise with rho = 0.9 loses about 8 % of the
    residual variance there and the sandwich's u comes out 10 % small (measured).  The shortfall is
    computed under the model and added back (two passes); for white noise it is the familiar
    n / (n - p) degrees-of-freedom correction.
    """
    r = np.asarray(residuals, dtype=float).ravel()
    n = r.size
    max_order = int(min(max_order, max(n // 10, 0)))
    var = float(np.mean((r - r.mean()) ** 2))
    if var <= 0 or max_order == 0:
        return ARNoise(np.zeros(0), var)
    acov = autocorrelation(r, max_order) * var
    noise = _levinson_aic(acov, n, max_order)
    if jacobian is None:
        return noise
    # the residuals' own mean is removed above: the constant is part of what was projected off
    columns = np.column_stack([np.ones(n), np.asarray(jacobian, dtype=float).reshape(n, -1)])
    u, s, _ = np.linalg.svd(columns, full_matrices=False)
    basis = u[:, s > s[0] * 1e-10]
    for _ in range(2):
        noise = _levinson_aic(acov + _projection_shortfall(noise, basis, max_order), n, max_order)
    return noise


def ar_sandwich_covariance(normal_matrix: np.ndarray, jacobian: np.ndarray, residuals: np.ndarray,
                           noise: ARNoise | BandNoise | None = None) -> Sandwich:
    """Sandwich covariance with the middle matrix J' Sigma J from an AR model of the residuals.

    For records too short for batch means (fewer than MIN_BLOCKS blocks of BLOCK_PER_TAU tau): the
    middle matrix is computed in the frequency domain, sum_k S(w_k) J^(w_k)* J^(w_k), with S the AR
    spectrum, so each parameter sees the noise at the frequencies its Jacobian column occupies (a
    sine's amplitude the noise at the sine's frequency).  A smooth parametric spectrum, not the
    residuals' periodogram: the fit has emptied the periodogram exactly where its columns live.
    Rows of ``jacobian`` are in time order, one instant each, uniformly sampled.
    """
    jacobian = np.asarray(jacobian, dtype=float)
    noise = noise or ar_noise_model(residuals, jacobian=jacobian)
    n = jacobian.shape[0]
    size = _grid_size(n)
    spectrum_j = np.fft.rfft(jacobian, size, axis=0)
    weights = np.full(spectrum_j.shape[0], 2.0)
    weights[0] = 1.0
    if size % 2 == 0:
        weights[-1] = 1.0
    s = noise.spectrum(2 * np.pi * np.arange(spectrum_j.shape[0]) / size) * weights / size
    middle = np.real((spectrum_j.conj() * s[:, None]).T @ spectrum_j)
    bread = np.linalg.pinv(np.asarray(normal_matrix, dtype=float))
    cov = bread @ middle @ bread
    dof = n / max(noise.order, 1) if isinstance(noise, ARNoise) else float("inf")   # a BandNoise's: PooledNoise
    return Sandwich(0.5 * (cov + cov.T), 0, 0, method=f"{noise.label} spectral sandwich", dof=float(dof))


def _grid_size(n: int) -> int:
    """FFT length for an n-sample record's spectral sums: a power of two >= 2n (no lag of the record wraps)."""
    return 1 << int(np.ceil(np.log2(2 * n)))


def checked_covariance(jacobian: np.ndarray, residuals: np.ndarray, white: np.ndarray,
                       tested: Whiteness | None = None, white_dof: float = float("inf")):
    """The policy in one call: (covariance, how it was made, Whiteness, effective dof of the covariance's
    estimate) for a least-squares fit (the dof: ``white_dof``, the fit's n - p, when white; the sandwich's).

    ``white`` is the fit's white-noise covariance sigma^2 (J'J)^-1, returned as it is when the
    residuals pass as white.  Correlated residuals: the batch-means sandwich when the record
    holds MIN_BLOCKS blocks of BLOCK_PER_TAU tau, else the AR-spectrum sandwich.  Rows of
    ``jacobian`` and ``residuals`` are in time order, one instant each.  ``tested``: the
    residuals' ``whiteness`` when the caller has it already (a tall fit tests first and builds
    its Jacobian only when the noise is correlated).
    """
    w = tested if tested is not None else whiteness(residuals)
    if not w.correlated:
        return white, "white noise: sigma^2 (J'J)^-1", w, float(white_dof)
    sandwich = correlated_sandwich(jacobian, residuals, w)
    return sandwich.covariance, sandwich.method, w, sandwich.dof


def correlated_sandwich(jacobian: np.ndarray, residuals: np.ndarray, tested: Whiteness) -> Sandwich:
    """``checked_covariance``'s covariance for correlated residuals, as a Sandwich (its ``dof`` too): the
    batch-means sandwich when the record holds MIN_BLOCKS blocks of BLOCK_PER_TAU tau, else the AR one."""
    jacobian = np.asarray(jacobian, dtype=float)
    normal = jacobian.T @ jacobian
    block = tested.block_length()
    sandwich = sandwich_covariance(normal, block_scores(jacobian, residuals, block), block)
    if sandwich.underresolved:
        return ar_sandwich_covariance(normal, jacobian, residuals)
    sandwich.method = f"batch-means sandwich, {sandwich.blocks} blocks of {sandwich.block} samples"
    return sandwich


# ---------------------------------------------------------------- one sensor, several short fits: a pooled spectrum

POOL_BAND_GROWTH = 1.25      # band edges grow geometrically by this factor once wider than a record's resolution
POOL_BAND_WIDTH = 2.0        # the narrowest band, in units of a record's resolution 1 / n
POOL_SEEN = 0.2              # a band is seen when at least this share of its noise survives the fits' projections


@dataclass
class BandNoise:
    """A piecewise-constant noise spectrum: ``levels`` (two-sided density per sample, as ARNoise.spectrum) in the
    bands between ``edges`` (cycles per sample, 0 .. 0.5).  ``seen`` marks the bands the residuals showed;
    an unseen band holds the larger level of its seen neighbours."""

    edges: np.ndarray
    levels: np.ndarray
    seen: np.ndarray

    label = "pooled-spectrum"

    def spectrum(self, omega: np.ndarray) -> np.ndarray:
        f = np.abs(np.asarray(omega, dtype=float)) / (2 * np.pi)
        return self.levels[_band_index(self.edges, f)]

    def scaled(self, level: float) -> BandNoise:
        return BandNoise(self.edges, self.levels * level, self.seen)


@dataclass
class PooledNoise:
    """The spectrum several fits of one sensor share, and each fit's own level against it (``pooled_noise_model``)."""

    noise: BandNoise
    levels: np.ndarray       # per fit: its residual power over what the pooled spectrum predicts for it
    p_values: np.ndarray     # per fit: F test of that level against 1 (one-sided, too much residual)
    dof: np.ndarray          # per fit: effective degrees of freedom of its residual power
    pooled: np.ndarray       # per fit: did it inform the pooled spectrum (False: its level stood out)
    stands_out: np.ndarray   # per fit: its level above warn_ratio^2 and significant (warn: the model misses it)
    ar_p_value: float        # chi-square test of one AR model of all pooled residuals against their band powers
    # what a variance stated from the bands rests on, for its effective degrees of freedom (``variance_dof``)
    observed: np.ndarray | None = None        # (F, m): each fit's residual power per band
    expected: np.ndarray | None = None        # (F, m, m): its expectation per unit level of each band's noise
    level_map: np.ndarray | None = None       # (m, m): d noise.levels / d (pooled fits' summed power per band)
    power_variance: np.ndarray | None = None  # (F, m): variance of each fit's band power under the model

    def for_fit(self, i: int) -> BandNoise:
        return self.noise.scaled(float(self.levels[i]))

    def variance_gradient(self, i: int, shares: np.ndarray) -> tuple[float, np.ndarray]:
        """A variance fit ``i`` states from the bands, v = levels[i] * shares @ noise.levels (``shares``: each
        band's part at unit level, ``band_variance_shares``), and its gradient (F, m) with respect to every
        fit's residual power per band, to first order: both the pooled band levels and the fit's own level
        (its residual power over what the bands predict for it) move with them."""
        full = self.noise.levels
        shares = np.asarray(shares, dtype=float)
        value = float(self.levels[i] * (shares @ full))
        gradient = np.zeros_like(self.observed)
        if value <= 0 or self.observed[i].sum() <= 0:
            return value, gradient
        gradient[i] += value / float(self.observed[i].sum())
        predicted = self.expected[i].sum(axis=0)          # the fit's total power per unit level of each band
        direction = shares / (shares @ full) - predicted / max(float(predicted @ full), 1e-300)
        gradient[self.pooled] += value * (direction @ self.level_map)[None, :]
        return value, gradient

    def gradient_variance(self, gradient: np.ndarray) -> float:
        """Variance of a quantity with this gradient (F, m) over the fits' band powers (independent, each a sum
        of |periodogram|^2 ordinates: var = mean^2 / ordinates)."""
        return float(np.sum(np.asarray(gradient) ** 2 * self.power_variance))

    def variance_dof(self, i: int, shares: np.ndarray) -> float:
        """Effective degrees of freedom (Welch-Satterthwaite, GUM G.4) of ``variance_gradient``'s variance:
        2 v^2 / var(v), at least 1."""
        value, gradient = self.variance_gradient(i, shares)
        return satterthwaite_dof(value, self.gradient_variance(gradient))


def satterthwaite_dof(variance: float, variance_of_variance: float) -> float:
    """Effective dof of a variance estimate from its own variance (a chi-square with nu dof: var = 2 v^2 / nu),
    at least 1; infinite when it is known exactly."""
    if variance_of_variance <= 0 or not np.isfinite(variance_of_variance):
        return float("inf")
    return float(max(2.0 * variance**2 / variance_of_variance, 1.0))


def band_variance_shares(jacobian: np.ndarray, rows: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Each band's part, at unit level, of the variances of rows @ theta under ``ar_sandwich_covariance`` with a
    BandNoise of these ``edges``: (q, m) for ``rows`` (q, p) = g' (J'J)^-1 of q quantities.  The sandwich's
    middle matrix is sum_k S(w_k) J^_k* J^_k, so g' cov g = sum_k S(w_k) |FFT(J v)_k|^2, v = (J'J)^-1 g."""
    jacobian = np.asarray(jacobian, dtype=float)
    n = jacobian.shape[0]
    size = _grid_size(n)
    spectrum = np.fft.rfft(jacobian @ np.atleast_2d(np.asarray(rows, dtype=float)).T, size, axis=0)
    weights = np.full(spectrum.shape[0], 2.0)
    weights[0] = 1.0
    if size % 2 == 0:
        weights[-1] = 1.0
    power = np.abs(spectrum) ** 2 * (weights / size)[:, None]
    band = _band_index(edges, np.arange(spectrum.shape[0]) / size)
    return np.stack([np.bincount(band, power[:, q], edges.size - 1) for q in range(power.shape[1])])


def _band_index(edges: np.ndarray, cycles: np.ndarray) -> np.ndarray:
    return np.clip(np.searchsorted(edges, np.minimum(cycles, 0.5), side="right") - 1, 0, edges.size - 2)


def pool_band_edges(shortest: int) -> np.ndarray:
    """Band edges (cycles per sample) for a pooled spectrum of records at least ``shortest`` samples long:
    POOL_BAND_WIDTH times a record's resolution (1 / shortest) wide at low frequencies (narrower bands
    rest on too few periodogram ordinates), growing by POOL_BAND_GROWTH above."""
    width = POOL_BAND_WIDTH / shortest
    edges = [0.0]
    while edges[-1] < 0.5:
        edges.append(edges[-1] + max(width, (POOL_BAND_GROWTH - 1.0) * edges[-1]))
    if 0.5 - edges[-2] < 0.5 * (edges[-2] - edges[-3]):
        edges.pop(-2)   # no sliver of a last band
    edges[-1] = 0.5
    return np.array(edges)


def _band_moments(jacobian: np.ndarray, residuals: np.ndarray, edges: np.ndarray):
    """One fit's observed residual power per band (periodogram sums, (m,)), its expectation per unit level
    of each band's noise after the fit's projection ((m, m): row = where the power shows, column = the
    noise band), and the same without the projection (the noise itself, for how much of a band survives).

    E|F(r)_k|^2 for r = (I - H) e, H = Q Q', is u' Sigma u - 2 Re(F(Q)_k F(Sigma Q)_k*) +
    F(Q)_k (Q' Sigma Q) F(Q)_k*: Toeplitz products by FFT on a grid of >= 2n points (exact there)."""
    r = np.asarray(residuals, dtype=float).ravel()
    n = r.size
    columns = np.column_stack([np.ones(n), np.asarray(jacobian, dtype=float).reshape(n, -1)])
    u, s, _ = np.linalg.svd(columns, full_matrices=False)
    basis = u[:, s > s[0] * 1e-10]
    size = _grid_size(n)
    bins = size // 2 + 1
    band = _band_index(edges, np.arange(bins) / size)
    m = edges.size - 1
    # each rfft bin stands for itself and its negative frequency (not 0 and the Nyquist bin)
    fold = np.full(bins, 2.0)
    fold[0] = fold[-1] = 1.0
    observed = np.bincount(band, np.abs(np.fft.rfft(r, size)) ** 2 * fold, m)
    f_basis = np.fft.rfft(basis, size, axis=0)
    lags = np.arange(n)
    expected = np.zeros((m, m))
    bare = np.zeros((m, m))
    for b in range(m):
        indicator = (band == b).astype(float)
        if not indicator.any():
            continue
        gamma = np.fft.irfft(indicator, size)[:n]
        kernel = np.zeros(size)
        kernel[:n] = (n - lags) * gamma
        kernel[size - n + 1:] = kernel[1:n][::-1]
        plain = np.real(np.fft.rfft(kernel))
        sigma_basis = np.fft.irfft(indicator[:, None] * f_basis, size, axis=0)[:n]
        f_sigma_basis = np.fft.rfft(sigma_basis, size, axis=0)
        inner = basis.T @ sigma_basis
        power = (plain - 2 * np.real(np.sum(f_basis * f_sigma_basis.conj(), axis=1))
                 + np.real(np.einsum("kp,pq,kq->k", f_basis, inner, f_basis.conj())))
        expected[:, b] = np.bincount(band, power * fold, m)
        bare[:, b] = np.bincount(band, plain * fold, m)
    return observed, expected, bare, n - basis.shape[1]


def _solve_levels(observed: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """Band levels >= 0 whose expected residual power matches the observed, each band's power weighted by
    its relative error (twice: the weights from the first fit)."""
    from scipy.optimize import nnls

    scale = np.maximum(observed, 1e-300) / np.maximum(np.diag(expected), 1e-300)   # a first level per band
    weight = 1.0 / np.maximum(observed, 1e-300)
    for _ in range(2):
        design = expected * scale[None, :] * weight[:, None]
        x, _ = nnls(design, observed * weight, maxiter=50 * expected.shape[1])
        levels = x * scale
        fitted = expected @ levels
        weight = 1.0 / np.maximum(fitted, 1e-3 * np.max(fitted))
    return levels


def pooled_noise_model(fits: list[tuple[np.ndarray, np.ndarray]], alpha: float = ALPHA,
                       warn_ratio: float = 1.15) -> PooledNoise:
    """The noise spectrum several least-squares fits of one sensor's record share, from all their residuals.

    ``fits``: (jacobian, residuals) per fit, rows in time order, one instant each, all at one sampling rate.
    A short fit's residuals say little about the noise where its own columns live (a sine fit empties
    the periodogram at its frequency); another fit, with its columns elsewhere, shows the noise there.
    The spectrum is piecewise constant in bands (``pool_band_edges``), and each band's level is found
    by matching every fit's residual power per band to its expectation after that fit's projection (a
    method of moments, the projection exact): a band emptied in one fit is read from the others.  A band
    none of the fits shows (less than POOL_SEEN of its noise survives) takes the larger level of its
    neighbours, and is marked unseen.

    Each fit keeps a level of its own, its residual power over what the pooled spectrum predicts for it
    (a step that shakes more, or a model that misses the motion, shows there).  A level above
    ``warn_ratio``^2 and significant at ``alpha`` (F test, effective dof from the expected power's spread
    over frequency) leaves that fit out of the pool (the worst first, one at a time, while two remain),
    which is then found again from the others; ``pooled`` says which fits the spectrum rests on.
    ``ar_p_value`` tests one AR model of the pooled fits against the same band powers (``_ar_band_test``):
    where it holds, a caller may keep the smoother AR answer.
    """
    shortest = min(np.asarray(r).size for _, r in fits)
    edges = pool_band_edges(shortest)
    moments = [_band_moments(j, r, edges) for j, r in fits]
    width = np.diff(edges)
    pooled = np.ones(len(fits), dtype=bool)
    for _ in range(len(fits)):
        observed = sum(mo[0] for mo, keep in zip(moments, pooled, strict=True) if keep)
        expected = sum(mo[1] for mo, keep in zip(moments, pooled, strict=True) if keep)
        bare = sum(mo[2] for mo, keep in zip(moments, pooled, strict=True) if keep)
        seen = expected.sum(axis=0) >= POOL_SEEN * np.maximum(bare.sum(axis=0), 1e-300)
        levels = _solve_levels(observed[seen], expected[np.ix_(seen, seen)])
        full = np.zeros(edges.size - 1)
        full[seen] = levels
        for b in np.flatnonzero(~seen):
            neighbours = [full[c] for c in (b - 1, b + 1) if 0 <= c < full.size and seen[c]]
            full[b] = max(neighbours) if neighbours else float(np.max(levels, initial=0.0))
        own, dof = np.empty(len(fits)), np.empty(len(fits))
        for i, (obs, exp_, _bare, dof_fit) in enumerate(moments):
            predicted = exp_ @ full
            own[i] = float(obs.sum() / predicted.sum()) if predicted.sum() > 0 else 1.0
            # a band of width w holds n w independent periodogram ordinates (2 dof each): a power spread
            # unevenly over frequency has fewer dof than the n - p of white residuals
            spread = float(np.sum(predicted**2 / width)) / (dof_fit * predicted.sum() ** 2)
            dof[i] = float(np.clip(2.0 / spread, 1.0, dof_fit)) if spread > 0 else float(dof_fit)
        pool_dof = max(float(dof[pooled].sum()), 1.0)
        p_values = np.array([float(_sps.f.sf(level, d, pool_dof)) for level, d in zip(own, dof, strict=True)])
        # the worst step that stands out leaves the pool, one at a time (it would inflate the reference the
        # others are judged by), while at least two remain
        stands_out = pooled & (own > warn_ratio**2) & (p_values < alpha)
        if not stands_out.any() or pooled.sum() <= 2:
            break
        pooled[int(np.argmax(np.where(stands_out, own, -np.inf)))] = False
    stands_out = (own > warn_ratio**2) & (p_values < alpha)
    kept = [fit for fit, keep in zip(fits, pooled, strict=True) if keep]
    ar_p = _ar_band_test(kept, [mo for mo, keep in zip(moments, pooled, strict=True) if keep], edges, seen)
    level_map = _level_map(expected[np.ix_(seen, seen)], levels, seen, full)
    observed_all = np.array([mo[0] for mo in moments])
    expected_all = np.array([mo[1] for mo in moments])
    power_variance = np.empty_like(observed_all)
    for i, (jacobian, residuals) in enumerate(fits):
        # each band power is a chi-square with the dof of its periodogram ordinates, net of the fit's projection
        power_variance[i] = 2.0 * (own[i] * (moments[i][1] @ full)) ** 2 / _band_power_dof(jacobian, residuals, edges)
    return PooledNoise(BandNoise(edges, full, seen), own, p_values, dof, pooled, stands_out, ar_p,
                       observed_all, expected_all, level_map, power_variance)


def _band_power_dof(jacobian: np.ndarray, residuals: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Satterthwaite dof of one fit's residual power per band (as ``_band_moments`` sums it), the noise taken
    flat within a band: 2 tr(WG)^2 / tr((WG)^2), G = F (I - H) F^H over the band's grid bins (F the DFT rows
    on the >= 2n grid, W the fold weights).  A band of K Fourier ordinates that no fit column reaches has
    2K; what the fit took out (its columns' share of the band) and the grid's overlap between ordinates
    are counted exactly, not assumed."""
    r = np.asarray(residuals, dtype=float).ravel()
    n = r.size
    columns = np.column_stack([np.ones(n), np.asarray(jacobian, dtype=float).reshape(n, -1)])
    u, s, _ = np.linalg.svd(columns, full_matrices=False)
    f_basis = np.fft.rfft(u[:, s > s[0] * 1e-10], _grid_size(n), axis=0)
    size = _grid_size(n)
    bins = size // 2 + 1
    band = _band_index(edges, np.arange(bins) / size)
    fold = np.full(bins, 2.0)
    fold[0] = fold[-1] = 1.0
    # the Dirichlet kernel sum_t<n exp(-2 pi i d t / size) for every bin distance d
    d = np.arange(-(bins - 1), bins)
    with np.errstate(divide="ignore", invalid="ignore"):
        dirichlet = (1 - np.exp(-2j * np.pi * d * n / size)) / (1 - np.exp(-2j * np.pi * d / size))
    dirichlet[d == 0] = n
    out = np.empty(edges.size - 1)
    for b in range(edges.size - 1):
        k = np.flatnonzero(band == b)   # contiguous bins: G's noise part D is Toeplitz, d[k - l]
        w, fq = fold[k], f_basis[k]
        lags = dirichlet[bins - k.size: bins + k.size - 1]
        trace = float(np.sum(w * (n - np.sum(np.abs(fq) ** 2, axis=1))))
        # tr((WG)^2) = sum w_k w_l |D_kl|^2 - 2 Re tr(Fq' W D W Fq) + |Fq' W Fq|^2, D applied by FFT convolution
        noise = float(np.sum(np.abs(lags) ** 2 * np.correlate(w, w, "full")))
        weighted = w[:, None] * fq
        size_b = _next_fast_len(3 * k.size - 2)
        d_weighted = np.fft.ifft(np.fft.fft(lags, size_b)[:, None] * np.fft.fft(weighted, size_b, axis=0),
                                 axis=0)[k.size - 1: 2 * k.size - 1]
        cross = float(np.real(np.vdot(weighted, d_weighted)))
        projected = float(np.sum(np.abs(fq.conj().T @ weighted) ** 2))
        square = noise - 2.0 * cross + projected
        out[b] = 2.0 * trace**2 / square if square > 0 else 1.0
    return np.maximum(out, 1.0)


def _level_map(expected: np.ndarray, levels: np.ndarray, seen: np.ndarray, full: np.ndarray) -> np.ndarray:
    """d full / d (summed observed power per band) at ``_solve_levels``' answer: the weighted least squares
    over the seen bands whose level is positive (the others held at zero), an unseen band following the
    neighbour whose level it took (``pooled_noise_model``)."""
    m = full.size
    fitted = expected @ levels
    weight = 1.0 / np.maximum(fitted, 1e-3 * max(float(np.max(fitted, initial=0.0)), 1e-300))
    active = levels > 0
    seen_map = np.zeros((levels.size, levels.size))
    if active.any():
        seen_map[active] = np.linalg.pinv(expected[:, active] * weight[:, None]) * weight[None, :]
    out = np.zeros((m, m))
    index = np.flatnonzero(seen)
    out[np.ix_(index, index)] = seen_map
    for b in np.flatnonzero(~seen):
        neighbours = [c for c in (b - 1, b + 1) if 0 <= c < m and seen[c]]
        source = max(neighbours, key=lambda c: full[c]) if neighbours else (
            int(index[np.argmax(levels)]) if index.size else None)
        if source is not None:
            out[b] = out[source]
    return out


def _ar_band_test(fits, moments, edges: np.ndarray, seen: np.ndarray) -> float:
    """p-value of one AR model of all the fits' residuals (their autocovariances summed, each fit's
    projection shortfall added back, as ar_noise_model) against the residual power they show per band.

    A smooth AR spectrum is precise where it is right (white, AR-like noise: two or three parameters
    from every sample), the bands are unbiased but each rests on a few seconds of data; a caller keeps
    the AR model unless this test rejects it."""
    n_total = sum(np.asarray(r).size for _, r in fits)
    max_order = int(min(AR_MAX_ORDER, max(min(np.asarray(r).size for _, r in fits) // 10, 1)))
    acov = np.zeros(max_order + 1)
    bases = []
    for jacobian, residuals in fits:
        r = np.asarray(residuals, dtype=float).ravel()
        acov += autocorrelation(r, max_order) * float(np.mean((r - r.mean()) ** 2)) * r.size
        columns = np.column_stack([np.ones(r.size), np.asarray(jacobian, dtype=float).reshape(r.size, -1)])
        u, sv, _ = np.linalg.svd(columns, full_matrices=False)
        bases.append((r.size, u[:, sv > sv[0] * 1e-10]))
    acov /= n_total
    noise = _levinson_aic(acov, n_total, max_order)
    for _ in range(2):
        shortfall = sum(_projection_shortfall(noise, basis, max_order) * n for n, basis in bases) / n_total
        noise = _levinson_aic(acov + shortfall, n_total, max_order)
    grid = np.linspace(0.0, 0.5, 8193)
    band = _band_index(edges, grid)
    density = np.bincount(band, noise.spectrum(2 * np.pi * grid), edges.size - 1)
    levels = density / np.maximum(np.bincount(band, minlength=edges.size - 1), 1)
    width = np.diff(edges)
    observed = sum(mo[0] for mo in moments)
    expected = np.zeros(edges.size - 1)
    variance = np.zeros(edges.size - 1)
    for _obs, exp_, _bare, dof_fit in moments:
        mine = exp_ @ levels
        expected += mine
        variance += mine**2 / np.maximum(dof_fit * width, 1.0)   # n w complex ordinates per band
    chi2 = float(np.sum((observed - expected)[seen] ** 2 / np.maximum(variance[seen], 1e-300)))
    return float(_sps.chi2.sf(chi2, int(seen.sum())))


# ---------------------------------------------------------------- noise slower than the longest block: a power law

LOW_FIRST_ORDINATE = 3       # the fit empties the lowest ordinates (offsets, drifts, slow shapes): fitted from here
LOW_OCTAVES_ABOVE = 2        # the power law is fitted over the band up to this many octaves above the cut
POWER_LAW_EXPONENTS = np.arange(0.1, 2.0001, 0.05)   # 1/f^beta up to a random walk's beta = 2


@dataclass
class PowerLawNoise:
    """A noise spectrum white + level |f|^-beta at low frequencies, fitted to one series' periodogram
    (Whittle likelihood) over ordinates ``first``..``last`` of an ``n``-point series; f in cycles per
    sample of that series, the density two-sided per sample (E|DFT_j|^2 / n).  ``p_value`` tests the
    power-law part against white noise over the same band (likelihood ratio, chi-square with 2 dof)."""

    white: float
    level: float
    beta: float
    p_value: float
    n: int
    first: int
    last: int

    def spectrum(self, f: np.ndarray) -> np.ndarray:
        f = np.abs(np.asarray(f, dtype=float))
        return self.white + self.level * np.power(np.maximum(f, 1e-300), -self.beta)

    @property
    def found(self) -> bool:
        return self.p_value < ALPHA and self.level > 0

    def to_dict(self) -> dict:
        return {"beta": self.beta, "p_value": self.p_value, "found": self.found,
                "band_cycles_per_sample": [self.first / self.n, self.last / self.n]}


def _whittle(power: np.ndarray, design: np.ndarray) -> tuple[np.ndarray, float]:
    """Non-negative coefficients of spectrum = design @ x that maximise the Whittle likelihood of the
    periodogram ``power`` (iteratively reweighted: each ordinate's power has sd equal to its mean),
    and the negative log-likelihood sum(log s + I / s)."""
    from scipy.optimize import nnls

    s = np.full(power.size, max(float(np.mean(power)), 1e-300))
    x = np.zeros(design.shape[1])
    for _ in range(8):
        x, _ = nnls(design / s[:, None], power / s)
        fitted = np.maximum(design @ x, 1e-12 * float(np.mean(power)) + 1e-300)
        if np.max(np.abs(fitted / s - 1.0)) < 1e-4:
            s = fitted
            break
        s = fitted
    return x, float(np.sum(np.log(s) + power / s))


def fit_power_law(series: np.ndarray, first: int, last: int) -> list[PowerLawNoise]:
    """``PowerLawNoise`` of each column of an (n, k) array of series (means removed) over periodogram
    ordinates ``first``..``last``, with one exponent for all columns (the axes of one sensor share the
    physics of their wander; one exponent from all of them is far steadier than one per axis).

    The exponent is searched over POWER_LAW_EXPONENTS, each column's white and power-law levels
    fitted for each; the likelihood ratio against white alone (same band, every column) gives the
    p-value (chi-square, k + 1 dof).  Used where the noise slower than a record's blocks must be
    extrapolated: the band is the lowest the record shows well, and the power law is the stated
    assumption about what lies below it."""
    x = np.asarray(series, dtype=float)
    x = x[:, None] if x.ndim == 1 else x
    n, k = x.shape
    last = int(min(last, (n - 1) // 2))
    first = int(max(1, first))
    if last - first < 8:
        return [PowerLawNoise(float(np.var(c)), 0.0, 0.0, 1.0, n, first, last) for c in x.T]
    j = np.arange(first, last + 1)
    # a taper keeps a steep spectrum's low-frequency power from leaking up the band (it would flatten the slope)
    taper = np.hanning(n + 2)[1:-1]
    taper /= np.sqrt(np.mean(taper**2))
    power = np.abs(np.fft.rfft((x - x.mean(axis=0)) * taper[:, None], axis=0)[first:last + 1]) ** 2 / n
    f = j / n
    white_only = np.mean(power, axis=0)
    null = float(np.sum(np.log(white_only) * j.size + np.sum(power / white_only, axis=0)))
    best = (np.inf, 0.0, [])
    for beta in POWER_LAW_EXPONENTS:
        design = np.column_stack([np.ones(j.size), f ** -beta])
        fits = [_whittle(power[:, c], design) for c in range(k)]
        nll = sum(fit[1] for fit in fits)
        if nll < best[0]:
            best = (nll, float(beta), [fit[0] for fit in fits])
    nll, beta, coefs = best
    statistic = max(2.0 * (null - nll), 0.0)
    p_value = float(_sps.chi2.sf(statistic, k + 1))
    return [PowerLawNoise(float(c[0]), float(c[1]), beta, p_value, n, first, last) for c in coefs]


LOW_PADDING = 8              # the low-frequency integral is summed on a grid this many times finer than 1 / record


def low_frequency_covariance(influence: np.ndarray, noise: PowerLawNoise, cut: int) -> np.ndarray:
    """What batch means over blocks shorter than the record miss of a noise with a long memory, as a
    covariance: the integral over |f| < f_cut of (S(f) - S(f_cut)) Re(H^(f) H^(f)*).

    ``influence`` (K, p): how each estimate moves per unit of the residual series ``noise`` was fitted
    to (K consecutive block sums; f in cycles per block, f_cut = cut / K).  Batch means over blocks of
    resolution f_cut see the spectrum below it as flat at S(f_cut); the power law's rise above that
    level is added.  The integral is summed on a grid LOW_PADDING times finer than 1 / K, since much
    of a 1/f noise's effect lies between the record's own ordinates (it bends the record as a whole);
    f = 0 is left out, which needs influences that sum to zero (an estimate that moves with the
    noise's mean over the record is the caller's to correct: that mean is part of an offset)."""
    h = np.asarray(influence, dtype=float)
    k, p = h.shape
    size = LOW_PADDING * k
    top = int(min(LOW_PADDING * cut, size // 2))
    if top < 2 or noise.level <= 0:
        return np.zeros((p, p))
    spectrum = np.fft.rfft(h, size, axis=0)[1:top]
    f = np.arange(1, top) / size
    excess = np.maximum(noise.spectrum(f) - noise.spectrum(cut / k), 0.0)
    # each positive ordinate stands for itself and its negative twin
    cov = 2.0 * np.real((spectrum.conj() * excess[:, None]).T @ spectrum) / size
    return 0.5 * (cov + cov.T)
