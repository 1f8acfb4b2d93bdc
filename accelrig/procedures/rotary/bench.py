"""Rotary oscillating bench (paper 001): sampling rate, sensitivity per axis, one test.

Inputs of one test: the MEMS recording in counts on its own clock (its
timestamps are NOT used: the procedure works in the sample-index domain), the
encoder angle on an accurate clock (a separate ``t,theta[,ref]`` log or the
``theta`` channel of the recording, then timestamped by the recording's ``t``),
the radius, which axis is tangential and which radial, the nominal MEMS rate
and optionally the excitation frequency.

Processing, as the paper and with its known weaknesses made explicit:

1. Reference from the encoder: a sine fit (with harmonics, on the accurate
   clock) gives f and theta0 with uncertainties; eq. 3-4 give the tangential
   amplitude r (2 pi f)^2 theta0 at f and the centripetal r omega0^2 / 2 at
   2f and at DC (omega0 = 2 pi f theta0).
2. True sampling rate: ``fit`` (default) fits the tangential axis in the
   sample-index domain (cycles per sample nu, IEEE 1057 four-parameter fit
   with harmonics sharing nu), fs = f / nu, u_r(fs)^2 = u_r(nu)^2 + u_r(f)^2;
   ``scan`` is the paper's: FFT peak frequency for candidate rates nominal
   +- 100 Hz in 1 Hz steps, pick the rate whose peak lands nearest f
   (quantised: u = 1 Hz / sqrt(12)).
3. 6-pole Butterworth low-pass at 40 Hz, zero phase (sosfiltfilt squares
   the magnitude: the amplitudes at f and 2f are divided by |H|^2 there), the
   ends trimmed by the filter's settling time, then zero-crossing trimming of
   the tangential axis to whole periods.
4. Amplitudes at f, 2f and DC of each axis: ``fit`` by a three-parameter fit
   (with harmonics) at the estimated nu of the UNFILTERED whole-period record
   (the fit is blind to the out-of-band noise the low-pass removes, so the
   filter adds nothing to it); ``scan`` by the paper's FFT bins of the
   filtered whole-period record, divided by the filter's gain.  Standard
   uncertainties come from the unfiltered fit in both (low-pass filtering
   leaves the noise at f untouched but shrinks the residuals, so a covariance
   from the filtered residuals would be several times too small), its
   residuals checked for whiteness (estimation.residuals: correlated noise
   gets the sandwich covariance, and the warnings say so).
   Before stage 3 the sample timing is checked: a record that lost samples
   without a trace is refused (the residual steps by whole sample periods
   between consecutive samples); a phase in sample index that wanders by more
   than a sample with no step is re-timed from its smooth path (a clock whose
   rate wandered), and refused when it is no smooth path; a clock that is
   merely slow or fast spaces every sample alike and passes; one whose rate
   moved gives the record's mean rate, its u widened to hold every rate seen.  Gaps the record knows of (the recorder's gap list, or
   its timestamps) are placed on the sample grid and only real samples enter
   the fits.
5. Sensitivity in counts per m/s^2: tangential axis from the f component,
   radial axis from the 2f component; the DC of the radial axis is reported
   and not used (it carries the offset and the bench's tilt, as the paper found).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import signal

from accelrig.errors import CalibrationError, DataError
from accelrig.estimation.distributions import chi2 as chi2_dist
from accelrig.estimation.gum import Contribution, UncertaintyBudget
from accelrig.estimation.sinefit import SineFit, fit_sine, fit_sines_known_frequency, interpolated_dft_frequency
from accelrig.geometry import AXES, parse_axis
from accelrig.procedures.rotary.settings import RATE_METHODS
from accelrig.recording import Recording, load_recording, read_table, utc_origin
from accelrig.result import CalibrationResult, Estimate
from accelrig.units import STANDARD_GRAVITY, normalise_unit

COMPONENTS = ("tangential", "centripetal", "dc")
FILTER_ORDER = 6
FILTER_CUTOFF = 40.0  # Hz (paper 001)
SCAN_HALF_WIDTH = 100.0  # Hz either side of nominal (paper 001: 1560 .. 1760 Hz at 1660)
SCAN_STEP = 1.0  # Hz
SETTLE_SECONDS = 0.5  # dropped at each end after filtering: far beyond the filter's ~0.1 s ring-down
HARMONICS = 3  # f, 2f, 3f: the centripetal cross-talk and motion distortion, kept out of the fundamental
RADIAL_F_LIMIT = 0.15  # m/s^2 at f on the radial axis: the paper's mounting check
RATE_OFF_LIMIT = 0.03  # a rate further than this from nominal is not a MEMS clock's error (datasheets: ~1 %)


@dataclass
class RotarySetup:
    """Geometry and reference inputs (defaults from paper 001).

    radius_uncertainty     standard uncertainty of r, m (paper: 0.5 mm, 0.3 %)
    geometry_uncertainty   relative standard uncertainty from bench imperfections
                           (paper: 0.06 % maximum, rectangular -> 0.06 % / sqrt(3))
    encoder_resolution     rad (paper: 0.01 degrees); its quantisation noise is
                           part of the encoder fit's residuals
    frequency_uncertainty  relative, of a given --frequency used without an
                           encoder fit of the frequency (never: the encoder
                           always gives f); kept for the campaign's budget notes
    ref_radius             radius of the optional reference accelerometer, m
    """

    radius: float = 0.170
    radius_uncertainty: float = 0.0005
    geometry_uncertainty: float = 0.0006 / np.sqrt(3.0)
    encoder_resolution: float = float(np.deg2rad(0.01))
    ref_radius: float = 0.145
    filter_cutoff: float = FILTER_CUTOFF
    g: float = STANDARD_GRAVITY

    def __post_init__(self) -> None:
        if not 0 < self.radius < 2:
            raise DataError(f"radius {self.radius} m is not plausible", "give it in metres, e.g. 0.170")
        if self.radius_uncertainty < 0 or self.geometry_uncertainty < 0:
            raise DataError("uncertainties of the reference must not be negative")


@dataclass
class EncoderLog:
    """Encoder angle (rad) on an accurate clock (s), and optionally a reference accelerometer (m/s^2)."""

    t: np.ndarray
    theta: np.ndarray
    ref: np.ndarray | None = None
    source: str = ""

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float)
        self.theta = np.asarray(self.theta, dtype=float)
        if self.t.shape != self.theta.shape or self.t.ndim != 1:
            raise DataError(f"{self.source or 'encoder'}: one time per angle is needed")
        if self.t.size < 16:
            raise DataError(f"{self.source or 'encoder'}: only {self.t.size} encoder samples")
        if np.any(np.diff(self.t) <= 0):
            raise DataError(f"{self.source or 'encoder'}: encoder times do not increase")
        if self.ref is not None:
            self.ref = np.asarray(self.ref, dtype=float)
            if self.ref.shape != self.t.shape:
                raise DataError(f"{self.source or 'encoder'}: ref has {self.ref.size} values for {self.t.size} times")

    @classmethod
    def from_recording(cls, rec: Recording) -> EncoderLog:
        """The ``theta`` (and ``ref``) channels of a recording, timestamped by its ``t``."""
        if "theta" not in rec.channels:
            raise DataError(
                f"{rec.meta.get('source', 'the MEMS recording')} has no 'theta' channel",
                "give the encoder log with --encoder E.csv (columns t,theta)",
            )
        return cls(rec.t, rec.channels["theta"], rec.channels.get("ref"), rec.meta.get("source", "theta channel"))

    def window(self, start: float, stop: float) -> EncoderLog:
        keep = (self.t >= start) & (self.t <= stop)
        return EncoderLog(self.t[keep], self.theta[keep], None if self.ref is None else self.ref[keep], self.source)


def read_encoder_csv(path: str | os.PathLike) -> EncoderLog:
    """Read an encoder log: header with ``t`` (s, accurate clock) and ``theta`` (rad), optional ``ref``."""
    path = Path(path)
    header, data, _ = read_table(path, ("t", "theta"), "an encoder log", "t,theta (seconds, radians)")
    col = {n: i for i, n in enumerate(header)}
    ref = data[:, col["ref"]] if "ref" in col else None
    return EncoderLog(data[:, col["t"]], data[:, col["theta"]], ref, str(path))


def parse_axis_name(spec: str, role: str) -> int:
    """The axis index of --tangential / --radial (the sign does not matter for amplitudes)."""
    parsed = parse_axis(spec)
    if parsed is None:
        raise DataError(f"--{role} {spec!r} is not a sensor axis", "use x, y or z")
    return parsed[0]


def mems_counts(rec: Recording) -> np.ndarray:
    """The MEMS samples in counts (n, 3): counts as recorded, or m/s^2 / g back through meta['scale']."""
    if rec.units == "counts":
        return rec.acc
    scale = rec.meta.get("scale")
    if not scale:
        raise DataError(
            f"{rec.meta.get('source', 'the MEMS recording')} is in {rec.units} and has no counts scale",
            "sensitivity is in counts per m/s^2: give the recording in counts (--units counts)",
        )
    return rec.to_si().acc / float(scale)


# ------------------------------------------------------------------ results


@dataclass
class AxisAmplitudes:
    """Components of one axis over the whole-period record, counts (filter gain corrected)."""

    at_f: float
    at_f_uncertainty: float
    at_2f: float
    at_2f_uncertainty: float
    dc: float
    dc_uncertainty: float


@dataclass
class AxisSensitivity:
    """Sensitivity of one axis in counts per m/s^2 from one component.

    ``noise_uncertainty`` and ``reference_uncertainty`` are relative (k = 1);
    ``uncertainty`` is absolute (k = 1), their root sum of squares.
    """

    axis: str
    component: str
    value: float
    uncertainty: float
    output_amplitude: float  # counts
    reference_amplitude: float  # m/s^2
    noise_uncertainty: float
    reference_uncertainty: float
    crosstalk_uncertainty: float = 0.0   # relative: another axis's line at this frequency seen through cross-axis

    def to_dict(self) -> dict:
        return {
            "value": self.value, "uncertainty": self.uncertainty, "component": self.component,
            "unit": "counts/(m/s^2)", "output_amplitude_counts": self.output_amplitude,
            "reference_amplitude": self.reference_amplitude,
            "relative_uncertainty_noise": self.noise_uncertainty,
            "relative_uncertainty_reference": self.reference_uncertainty,
            "relative_uncertainty_crosstalk": self.crosstalk_uncertainty,
        }


@dataclass
class RotaryTest:
    """Outcome of one rotary test."""

    rate_method: str
    sample_rate: Estimate
    nominal_rate: float
    frequency: Estimate
    theta0: Estimate
    reference: dict  # component -> {"value", "uncertainty", "budget"}
    amplitudes: dict[str, AxisAmplitudes]
    sensitivity: dict[str, AxisSensitivity]  # the used ones: tangential axis, radial axis
    dc_sensitivity: AxisSensitivity
    tangential_axis: str
    radial_axis: str
    up_axis: str
    n_periods: int
    n_samples: int
    filter_gain: dict
    quality: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    bland_altman: dict | None = None
    arrays: dict = field(default_factory=dict)

    def to_json_dict(self) -> dict:
        return {
            "procedure": "rotary",
            "rate_method": self.rate_method,
            "sample_rate_hz": {"value": self.sample_rate.value, "uncertainty": self.sample_rate.uncertainty,
                               "nominal": self.nominal_rate},
            "frequency_hz": {"value": self.frequency.value, "uncertainty": self.frequency.uncertainty},
            "theta0_rad": {"value": self.theta0.value, "uncertainty": self.theta0.uncertainty},
            "reference": {k: {kk: vv for kk, vv in v.items()} for k, v in self.reference.items()},
            "sensitivity": {axis: s.to_dict() for axis, s in self.sensitivity.items()},
            "dc_sensitivity": {self.radial_axis: self.dc_sensitivity.to_dict(),
                               "note": "from the radial axis's DC part: carries the offset and the bench tilt; "
                                       "reported, not used (paper 001)"},
            "amplitudes_counts": {a: vars(v) for a, v in self.amplitudes.items()},
            "axes": {"tangential": self.tangential_axis, "radial": self.radial_axis, "up": self.up_axis},
            "n_periods": self.n_periods,
            "n_samples": self.n_samples,
            "filter_gain_squared": self.filter_gain,
            "quality": self.quality,
            "bland_altman": self.bland_altman,
            "warnings": list(self.warnings),
        }

    def to_calibration_result(self) -> CalibrationResult:
        """As the common result type, the test's tables in ``details``.  No canonical correction: one
        test gives two gains and no offsets, and accelrig never fills the rest with guesses."""
        params = {"sample_rate": self.sample_rate, "frequency": self.frequency}
        for axis, s in self.sensitivity.items():
            params[f"sensitivity_{axis}"] = Estimate(s.value, s.uncertainty, "counts/(m/s^2)")
        table = self.to_json_dict()
        return CalibrationResult(
            procedure="rotary", method=f"rotary bench, rate by {self.rate_method}", model="q_o = S a_ref",
            correction=None, parameters=params, quality=dict(self.quality),
            settings={"tangential": self.tangential_axis, "radial": self.radial_axis,
                      "nominal_rate": self.nominal_rate},
            warnings=list(self.warnings),
            details={k: v for k, v in table.items() if k not in ("procedure", "quality", "warnings")},
            parameter_meaning=("sensitivity_k: counts per m/s^2 of the axis against the bench's encoder "
                               "reference (q = S a_ref); the MEMS sample rate and the excitation frequency are "
                               "measured on the way (no correction: one test gives two gains and no offsets)"),
        )


# ------------------------------------------------------------------ pieces


def butterworth(fs: float, cutoff: float = FILTER_CUTOFF):
    if cutoff >= fs / 2:
        raise DataError(f"the {cutoff:g} Hz low-pass is above the Nyquist frequency of {fs:.1f} Hz")
    return signal.butter(FILTER_ORDER, cutoff, fs=fs, output="sos")


def zero_phase_gain(sos, frequency: float, fs: float) -> float:
    """|H(f)|^2: the gain of the forward-backward (sosfiltfilt) filter at ``frequency``."""
    _, h = signal.sosfreqz(sos, worN=[frequency], fs=fs)
    return float(np.abs(h[0]) ** 2)


def scan_sample_rate(y: np.ndarray, frequency: float, nominal_rate: float,
                     half_width: float = SCAN_HALF_WIDTH, step: float = SCAN_STEP) -> tuple[float, float]:
    """The paper's rate scan (Fig. 3): FFT peak frequency for each candidate rate, keep the best.

    For a candidate fs_c the spectral peak sits at bin m (independent of fs_c)
    and reads m fs_c / N Hz; the rate whose reading is nearest the excitation
    frequency wins.  Returns (rate, standard uncertainty): the 1 Hz grid is a
    rectangular quantisation (step / sqrt(12)) and the peak bin adds at most
    one sample of the N in the record.
    """
    n = y.size
    spectrum = np.abs(np.fft.rfft(y - y.mean()))
    m = int(np.argmax(spectrum[1:])) + 1
    candidates = np.arange(nominal_rate - half_width, nominal_rate + half_width + step / 2, step)
    errors = np.abs(m * candidates / n - frequency)
    best = int(np.argmin(errors))
    if best in (0, candidates.size - 1):
        raise CalibrationError(
            f"the rate scan ended at the edge of its range ({candidates[best]:.0f} Hz, nominal {nominal_rate:g} +- "
            f"{half_width:g} Hz)",
            "check --nominal-rate and --frequency, or use --rate-method fit",
        )
    rate = float(candidates[best])
    u = float(np.sqrt(step**2 / 12.0 + (rate / n) ** 2 / 3.0))
    return rate, u


def whole_periods(y: np.ndarray, period_samples: float, start: int, stop: int) -> tuple[int, int, int]:
    """Zero-crossing trimming: first and last upward zero crossing of ``y`` (mean removed)
    inside [start, stop), so the slice holds whole periods.  Returns (first, last, periods)."""
    seg = y[start:stop] - np.mean(y[start:stop])
    up = np.flatnonzero((seg[:-1] < 0) & (seg[1:] >= 0)) + 1
    # a crossing closer than half a period to the previous kept one is noise on a slow slope
    kept = []
    for k in up:
        if not kept or k - kept[-1] > 0.5 * period_samples:
            kept.append(int(k))
    if len(kept) < 3:
        raise CalibrationError(
            f"only {max(len(kept) - 1, 0)} whole periods found on the tangential axis after trimming",
            "record longer (the paper records 40 s) or check --tangential",
        )
    return start + kept[0], start + kept[-1], len(kept) - 1


def _fft_components(y: np.ndarray, bin_f: int) -> tuple[float, float, float]:
    """Amplitudes at bins m, 2m and the DC of a whole-period record (paper's FFT)."""
    n = y.size
    spectrum = np.fft.rfft(y)
    a1 = 2.0 * np.abs(spectrum[bin_f]) / n
    a2 = 2.0 * np.abs(spectrum[2 * bin_f]) / n if 2 * bin_f < spectrum.size else float("nan")
    return float(a1), float(a2), float(spectrum[0].real / n)


# ------------------------------------------------------------------ the test


def analyse_test(
    mems: Recording,
    encoder: EncoderLog | None,
    tangential: str,
    radial: str,
    nominal_rate: float,
    frequency: float | None = None,
    rate_method: str = "fit",
    setup: RotarySetup | None = None,
    keep_arrays: bool = False,
) -> RotaryTest:
    """Process one rotary test (see the module docstring): each numbered stage is one function below."""
    setup = setup or RotarySetup()
    i_t, i_r, i_up = check_test_inputs(tangential, radial, nominal_rate, frequency, rate_method)
    real = checked_counts(mems)
    source = mems.meta.get("source", "MEMS recording")
    warnings: list[str] = []
    # sample positions on the MEMS's own sample grid: gaps the record knows of are kept as gaps
    index, gap_note = sample_positions(mems, nominal_rate)
    if gap_note:
        warnings.append(gap_note)
    counts = on_full_grid(index, real)   # for the filter and the spectra only; every fit uses the real samples
    if encoder is None:
        encoder = EncoderLog.from_recording(mems)
    enc = overlapping_encoder(mems, encoder, counts.shape[0], nominal_rate)
    ref = encoder_reference(enc, frequency, setup)                                         # 1
    nu_peak = excitation_on_tangential(counts[:, i_t], ref.frequency, nominal_rate, AXES[i_t], source)
    f = ref.frequency
    rate_fit = None
    if rate_method == "fit":                                                               # 2
        rate_fit, nu, fs, u_fs = sample_rate_by_fit(real[:, i_t], nu_peak, f, ref.u_f_rel, index)
        fs_for_filter = fs
    else:
        # the paper scans the filtered, whole-period record: filter at nominal rate first to find the periods
        fs_for_filter = nominal_rate
    timing = check_sample_timing(index, real[:, i_t], rate_fit.frequency if rate_fit else nu_peak, source, rate_fit)
    if timing.get("retime"):
        index, rate_fit, nu, fs, u_fs = retime(index, real[:, i_t], timing, rate_method, nu_peak, f, ref.u_f_rel,
                                               source, warnings)
        fs_for_filter = fs
    sos, filtered, seg, periods = filter_and_trim(counts, i_t, f, fs_for_filter, setup.filter_cutoff,  # 3
                                                  nominal_rate, source)
    if rate_method == "scan":
        fs, u_fs, nu, sos, filtered = sample_rate_by_scan(counts, filtered, seg, i_t, f, nominal_rate, sos,
                                                          setup.filter_cutoff)
    # a clock whose rate moved during the record (not enough to refuse): the mean rate, u as wide as it moved
    wandered = clock_wander(timing if timing and "p_value" in timing else None, nu)
    if wandered is not None:
        u_fs = float(np.hypot(u_fs, fs * wandered["relative_uncertainty"]))
        timing["rate_wander"] = wandered
        warnings.append(
            f"the sample clock's rate moved during the record: between stretches of it the rate was up to "
            f"{1e6 * wandered['largest_relative']:.0f} ppm ({fs * wandered['largest_relative']:.2g} Hz) off the "
            f"record's mean (the phase of the motion, counted in samples, wanders: chi-square p = "
            f"{wandered['p_value']:.2g}); the rate given is the record's mean and its u holds every rate seen "
            "(rectangular); record with timestamps to follow the clock, or keep the device's temperature steady")
    gain = {"at_f": zero_phase_gain(sos, f, fs), "at_2f": zero_phase_gain(sos, 2 * f, fs)}
    amplitudes, noise = axis_amplitudes(index, real, filtered, seg, f, fs, nu, rate_method, gain)   # 4
    # the encoder's own 2nd harmonic: (2 omega)^2 theta_2 against omega^2 theta_1 on the tangential axis
    motion_2f_share = 4.0 * float(ref.fit.amplitude[1] / ref.fit.amplitude[0]) if ref.fit.harmonics > 1 else 0.0
    check_axis_roles(amplitudes, i_t, i_r, f, motion_2f_share)
    sensitivity, dc_sens = sensitivities(amplitudes, ref.components, i_t, i_r)            # 5

    amp_t, amp_r = amplitudes[AXES[i_t]], amplitudes[AXES[i_r]]
    fits = ([("sample-rate fit", rate_fit)] if rate_fit is not None else []) + [
        (f"axis {AXES[i]} amplitudes", noise[AXES[i]]) for i in (i_t, i_r)]
    for what, fit in fits:
        if fit.whiteness is not None and fit.whiteness.correlated:
            warnings.append(f"{what}: {fit.whiteness.describe()}; u from the {fit.covariance_method}")
    radial_at_f = amp_r.at_f / sensitivity[AXES[i_r]].value
    a_tan = ref.components["tangential"]["value"]
    if radial_at_f > RADIAL_F_LIMIT * (a_tan / 49.0):
        warnings.append(
            f"the radial axis {AXES[i_r]} carries {radial_at_f:.3f} m/s^2 at f (the paper's mounting limit is "
            f"{RADIAL_F_LIMIT} m/s^2 at 49 m/s^2 tangential): check the sensor's alignment on the disk"
        )
    if abs(fs / nominal_rate - 1) > RATE_OFF_LIMIT:
        judged = (timing or {}).get("jumps", {}).get("judged_share", 0.0)
        cause = (f"no sample steps off the grid were seen ({judged:.0%} of the record steep enough to show one), so "
                 "no samples were lost: check --nominal-rate" if judged > 0 else
                 "the signal is too flat for lost samples to show, so a steady loss cannot be told from the clock: "
                 "check --nominal-rate and the link")
        warnings.append(
            f"the sample rate found, {fs:.1f} Hz, is {100 * (fs / nominal_rate - 1):+.1f} % off the nominal "
            f"{nominal_rate:g} Hz: beyond what a MEMS clock drifts; {cause}"
        )
    up_counts = amplitudes[AXES[i_up]].dc
    quality = {
        "encoder_residual_sd_rad": ref.fit.residual_sd,
        "encoder_harmonic_distortion": float(np.sqrt(np.sum(ref.fit.amplitude[1:] ** 2)) / ref.theta0),
        "radial_axis_at_f_m_s2": float(radial_at_f),
        "tangential_axis_at_2f_m_s2": float(amp_t.at_2f / sensitivity[AXES[i_t]].value),
        "up_axis_dc_counts": float(up_counts),
        "up_axis_dc_over_g": float(up_counts / setup.g),
        "rate_offset_from_nominal": float(fs / nominal_rate - 1),
    }
    if rate_fit is not None:
        quality["rate_fit_residual_sd_counts"] = rate_fit.residual_sd
        quality["rate_fit_iterations"] = rate_fit.n_iterations
    quality["sample_timing"] = timing
    quality["noise"] = {what: {"covariance_method": fit.covariance_method,
                               "whiteness": fit.whiteness.to_dict() if fit.whiteness is not None else None}
                        for what, fit in fits}
    quality["samples_missing"] = int(counts.shape[0] - real.shape[0])
    bland = _bland_altman_reference(enc, ref.fit, setup) if enc.ref is not None else None
    arrays = {"filtered_tangential": filtered[seg, i_t], "filtered_radial": filtered[seg, i_r]} if keep_arrays else {}
    return RotaryTest(
        rate_method=rate_method,
        sample_rate=Estimate(float(fs), float(u_fs), "Hz"),
        nominal_rate=float(nominal_rate),
        frequency=Estimate(float(f), float(ref.fit.frequency_uncertainty), "Hz"),
        theta0=Estimate(ref.theta0, ref.u_theta0, "rad"),
        reference=ref.components,
        amplitudes=amplitudes,
        sensitivity=sensitivity,
        dc_sensitivity=dc_sens,
        tangential_axis=AXES[i_t],
        radial_axis=AXES[i_r],
        up_axis=AXES[i_up],
        n_periods=periods,
        n_samples=seg.stop - seg.start,
        filter_gain=gain,
        quality=quality,
        warnings=warnings,
        bland_altman=bland,
        arrays=arrays,
    )


def check_test_inputs(tangential: str, radial: str, nominal_rate: float, frequency: float | None,
                      rate_method: str) -> tuple[int, int, int]:
    """The test's settings make sense: returns the indexes of the tangential, radial and up axes."""
    if rate_method not in RATE_METHODS:
        raise DataError(f"rate method {rate_method!r} is not one of {', '.join(RATE_METHODS)}")
    if not nominal_rate or nominal_rate <= 0:
        raise DataError("the nominal MEMS rate must be positive", "give --nominal-rate HZ")
    if frequency is not None and frequency <= 0:
        raise DataError(f"--frequency {frequency} must be positive")
    i_t = parse_axis_name(tangential, "tangential")
    i_r = parse_axis_name(radial, "radial")
    if i_t == i_r:
        raise DataError(f"--tangential {tangential} and --radial {radial} name the same axis")
    return i_t, i_r, 3 - i_t - i_r


def checked_counts(mems: Recording) -> np.ndarray:
    """The MEMS samples in counts, refused when they cannot be counts or sit at the int16 full scale."""
    counts = mems_counts(mems)
    if counts.shape[0] and np.median(np.linalg.norm(counts, axis=1)) < 100:
        # gravity alone is thousands of counts on any MEMS range: these are not counts
        raise DataError(f"{mems.meta.get('source', 'the MEMS recording')}: the values are far too small for counts",
                        "give a recording in counts, or its units (--units m/s2) with the counts scale in its metadata")
    clipped = np.count_nonzero((counts >= 32767) | (counts <= -32768))
    if clipped:
        raise DataError(f"{mems.meta.get('source', 'MEMS recording')}: {clipped} samples sit at the int16 full scale "
                        "(clipped)", "lower the oscillation angle or set a larger range")
    return counts


# Sample timing: a record that lost samples without saying where breaks the sample-index model
# (the motion's phase, counted in samples, jumps at every loss).  Judged on TIMING_SEGMENTS
# stretches of the record: their phases against one steady sine must agree within their
# uncertainties (p below TIMING_FALSE_ALARM refuses), and the disagreement must be worth at least
# a sample (a clock cannot do that within a test; lost samples do).
TIMING_SEGMENTS = 20
TIMING_FALSE_ALARM = 1e-6
# Below the refusal, a phase that wanders (p below WANDER_LEVEL) with no step is a clock whose rate
# moved during the record: the record's mean rate stands, and its u carries how far it moved.
WANDER_LEVEL = 1e-3
WANDER_DEGREE = 6     # the smoothest polynomial that follows the phase of a clock warming or wandering


def sample_positions(mems: Recording, nominal_rate: float) -> tuple[np.ndarray, str | None]:
    """Each real sample's position on the MEMS's sample grid, and a note when the record has gaps.

    Gaps come from the record's metadata (``gaps``: the recorder's sample counter) or, failing
    that, from its timestamps: a step of about m sample periods is m - 1 samples missing.  The
    MEMS clock's rate is not trusted, but a gap of a whole sample is far beyond its error.
    Without either, every sample is taken to follow the previous one (checked later by
    ``check_sample_timing``).
    """
    n = len(mems)
    positions = np.arange(n, dtype=float)
    gaps = [g for g in mems.meta.get("gaps") or [] if isinstance(g, dict) and int(g.get("missing", 0)) > 0]
    where = "metadata's gap list"
    if gaps:
        for g in gaps:
            positions[min(int(g["index"]), n):] += int(g["missing"])
    elif n > 2:
        dt = np.diff(np.asarray(mems.t, dtype=float))
        step = float(np.median(dt))
        if step > 0 and np.any(dt > 1.5 * step):
            positions = np.concatenate([[0.0], np.cumsum(np.maximum(np.round(dt / step), 1.0))])
            where = "timestamps"
    missing = int(positions[-1] + 1 - n) if n else 0
    if missing <= 0:
        return np.arange(n, dtype=float), None
    runs = int(np.count_nonzero(np.diff(positions) > 1))
    return positions, (f"{missing} MEMS samples ({missing / (n + missing):.1%}) are missing in {runs} gaps (from the "
                       f"record's {where}): kept as gaps, each fit uses the real samples at their places on the "
                       "sample grid")


def on_full_grid(positions: np.ndarray, real: np.ndarray) -> np.ndarray:
    """The samples on the whole sample grid, gaps bridged linearly: for the low-pass filter and the
    spectra only (a filter needs uniform samples); no fit uses a bridged value."""
    if positions.size == 0 or positions[-1] == positions.size - 1:
        return real
    grid = np.arange(int(positions[-1]) + 1, dtype=float)
    return np.column_stack([np.interp(grid, positions, real[:, j]) for j in range(real.shape[1])])


def phase_wander(t: np.ndarray, y: np.ndarray, frequency: float, segments: int = TIMING_SEGMENTS) -> dict | None:
    """Phase of one steady sine fitted on stretches of the record, against a straight line in time.

    Returns the deviations (rad), their uncertainties (noise checked for whiteness), the chi-square
    p-value of the line (dof segments - 2) and the largest deviation; None when the record holds
    too few periods for the test (fewer than 3 per stretch and 4 stretches).
    """
    periods = frequency * (t[-1] - t[0])
    k = int(min(segments, periods // 3))
    if k < 4:
        return None
    edges = np.linspace(0, t.size, k + 1).astype(int)
    phases, sds, centres = [], [], []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        fit = fit_sine(t[a:b], y[a:b], frequency=frequency, harmonics=HARMONICS, fit_frequency=False,
                       check_noise=True)
        phases.append(float(fit.phase[0]))
        sds.append(float(fit.phase_uncertainty[0]))
        centres.append(float(np.mean(t[a:b])))
    phases = np.unwrap(np.array(phases))
    sds, centres = np.maximum(np.array(sds), 1e-12), np.array(centres)
    design = np.column_stack([np.ones(k), centres - centres.mean()]) / sds[:, None]
    coef, *_ = np.linalg.lstsq(design, phases / sds, rcond=None)
    deviation = phases - (design * sds[:, None]) @ coef
    chi2 = float(np.sum((deviation / sds) ** 2))
    return {"segments": k, "chi2": chi2, "dof": k - 2, "p_value": float(chi2_dist.sf(chi2, k - 2)),
            "max_deviation_rad": float(np.max(np.abs(deviation))), "deviation_rad": deviation.tolist(),
            "uncertainty_rad": sds.tolist(), "centre": centres.tolist(), "span": [float(t[0]), float(t[-1])]}


def smooth_phase_path(wander: dict):
    """The stretches' phase deviations smoothed by a weighted Legendre polynomial in the sample position
    (degree 2 up, the first whose chi-square passes at 1 %, at most WANDER_DEGREE): a stretch's phase is
    far noisier than the whole record's, and differences of neighbours would pass their noise for a move.
    Returns (coefficients, degree, chi2, to_x) with ``to_x`` mapping positions onto the polynomial's [-1, 1]."""
    deviation, sd, centre = (np.asarray(wander[key]) for key in ("deviation_rad", "uncertainty_rad", "centre"))
    first, last = wander["span"]
    half = (last - first) / 2.0
    x = (centre - first) / half - 1.0
    k = deviation.size
    for degree in range(2, min(WANDER_DEGREE, k - 2) + 1):   # k >= 4 stretches: degree 2 always fits
        design = np.polynomial.legendre.legvander(x, degree) / sd[:, None]
        coef, *_ = np.linalg.lstsq(design, deviation / sd, rcond=None)
        chi2 = float(np.sum((design @ coef - deviation / sd) ** 2))
        if chi2_dist.sf(chi2, k - degree - 1) > 0.01:
            break
    return coef, degree, chi2, (lambda positions: (np.asarray(positions, dtype=float) - first) / half - 1.0)


def clock_wander(wander: dict, nu: float) -> dict | None:
    """How far the sample clock's rate strayed from the record's mean rate, from the phase wander.

    A clock running locally fast by a fraction e packs more samples into each period, so the phase
    per sample falls behind the whole-record line: e = -(d phase deviation / d sample) / (2 pi nu),
    from the smoothed phase path (``smooth_phase_path``: its slope follows a warming crystal's smooth
    drift to the record's two ends).  The rate the fit reports is the record's mean; the rate at any
    moment of the record lay within the largest |e| of it.  GUM type B, rectangular with that
    half-width: u_r = half-width / sqrt 3, so +-2u holds every rate the clock took (at the start, at
    the end).  Only when the phases disagree (p below WANDER_LEVEL): a steady clock adds nothing.
    None then.
    """
    if wander is None or wander["p_value"] >= WANDER_LEVEL:
        return None
    coef, degree, chi2, _ = smooth_phase_path(wander)
    first, last = wander["span"]
    grid = np.linspace(-1.0, 1.0, 201)
    slope = np.polynomial.legendre.legval(grid, np.polynomial.legendre.legder(coef)) / ((last - first) / 2.0)
    local = -slope / (2 * np.pi * nu)
    largest = float(np.max(np.abs(local)))
    return {"largest_relative": largest, "relative_uncertainty": largest / np.sqrt(3.0), "degree": degree,
            "chi2": chi2, "dof": len(wander["deviation_rad"]) - degree - 1, "p_value": wander["p_value"],
            "start_relative": float(local[0]), "end_relative": float(local[-1])}


def retimed_positions(positions: np.ndarray, wander: dict, nu: float) -> np.ndarray:
    """Each sample's place in time, in mean sample periods, from the smoothed phase path.

    A stretch whose phase runs ahead of the whole-record line by d rad was sampled d / (2 pi nu)
    sample periods later than its index says (the clock ran slow before it, or samples were lost
    where the signal is too flat for a step to show).  The correction's own line is taken out, so
    the record's mean rate stays what the whole-record fit finds."""
    coef, _, _, to_x = smooth_phase_path(wander)
    shift = np.polynomial.legendre.legval(to_x(positions), coef) / (2 * np.pi * nu)
    shift -= np.polyval(np.polyfit(positions, shift, 1), positions)
    return positions + shift


def retime(index: np.ndarray, y_t: np.ndarray, timing: dict, rate_method: str, nu_peak: float, f: float,
           u_f_rel: float, source: str, warnings: list[str]):
    """A phase that wanders by more than a sample with no whole-sample step: the samples are placed in time
    from the smooth phase path (``retimed_positions``) and the rate fitted again on those places.  Refused
    when the re-timed phase still wanders beyond a sample (the path is no smooth curve: a step the jump
    test could not see), or with the paper's scan, which needs a uniform grid.  Returns (index, rate_fit,
    nu, fs, u_fs) on the new places; the warning says what was done and why the rate is the record's mean."""
    if rate_method != "fit":
        raise timing_refusal(source, timing, "the paper's rate scan filters a uniform sample grid and cannot follow "
                                             "it (--rate-method fit re-times the samples from the phase path)")
    before = timing["max_deviation_samples"]
    index = retimed_positions(index, timing, timing["nu"])
    rate_fit, nu, fs, u_fs = sample_rate_by_fit(y_t, nu_peak, f, u_f_rel, index)
    after = phase_wander(index, y_t, nu)
    if after is not None:
        after["max_deviation_samples"] = float(after["max_deviation_rad"] / (2 * np.pi * nu))
        if wanders_beyond_a_sample(after):
            raise timing_refusal(source, timing, "re-timing the samples from the smooth phase path left "
                                                 f"{after['max_deviation_samples']:.1f} sample periods of it: the "
                                                 "path has a step, not a smooth curve (samples lost where the "
                                                 "signal is too flat to show a step)")
        timing["after_retiming"] = {k: after[k] for k in ("p_value", "chi2", "dof", "max_deviation_samples")}
    judged = timing["jumps"]["judged_share"]
    cause = ("no whole-sample step was seen where the signal is steep enough to show one "
             f"({judged:.0%} of the record), so the clock's rate wandered"
             if judged >= 0.3 else
             f"the signal is steep enough to show a lost sample in only {judged:.0%} of the record, so a clock "
             "that wandered cannot be told from samples lost (then the rate is not the device's)")
    warnings.append(
        f"the phase of the motion, counted in samples, wandered by up to {before:.1f} sample periods over the "
        f"record: {cause}. The samples were re-timed from the smoothed phase path before the amplitudes were "
        "fitted, so the sensitivities are those of the motion as it was; the rate is the record's mean "
        "(record with timestamps to follow the clock, or keep the device's temperature steady)")
    return index, rate_fit, nu, fs, u_fs


def check_sample_timing(positions: np.ndarray, y_t: np.ndarray, nu: float, source: str,
                        fit: SineFit | None = None) -> dict | None:
    """Refuse a record whose samples do not follow one another (samples lost without a trace).

    The tangential axis is a steady sine in the sample index only if every sample is where the
    index says.  A lost sample shifts the rest of the record by one period of the sample clock:
    the residual of a whole-record fit steps by the signal's change over one sample there
    (``sample_jumps``: scattered, burst or steady loss alike), and over a record the phase wanders
    far beyond its uncertainty (``phase_wander``: losses where the signal is too flat for a step
    to show).  5 % scattered loss: about -4 % to -14 % sensitivity; steady loss keeps the
    sensitivity but the rate found is not the device's.  ``fit``: a whole-record sine fit at
    ``positions`` (the rate fit), made here at ``nu`` when not given.
    """
    if fit is None:
        fit = fit_sine(positions, y_t, frequency=nu, harmonics=HARMONICS, fit_frequency=False)
    jumps = sample_jumps(positions, fit)
    n = positions.size
    if jumps["steps"]:
        lost, repeated = jumps["lost"], jumps["repeated"]
        what = " and ".join(part for part in (f"{lost} lost" if lost else "", f"{repeated} repeated"
                                               if repeated else "") if part)
        estimate = jumps["estimated_off_grid"]
        raise CalibrationError(
            f"{source}: samples were lost without a trace: the sample count does not match the motion. Between "
            f"consecutive samples the tangential axis steps by a whole sample period {jumps['steps']} times ({what}), "
            f"seen where the signal is steep enough ({jumps['judged_share']:.0%} of the record): about "
            f"{estimate:.0f} samples ({estimate / (n + estimate):.2%}) off the sample grid over the whole record. "
            "Lost samples at a steady pace would pass for a slow clock and give a rate that is not the device's; "
            "scattered ones move the sensitivity",
            "record the MEMS with its timestamps or its recorder's gap list (accelrig record keeps both) so the "
            "gaps can be placed, or re-record over a steady link",
        )
    wander = phase_wander(positions, y_t, nu)
    if wander is None:
        return {"jumps": jumps}
    wander["max_deviation_samples"] = float(wander["max_deviation_rad"] / (2 * np.pi * nu))
    wander["nu"] = float(nu)
    wander["jumps"] = jumps
    # beyond a sample with no step in it: the samples are re-timed from the smooth phase path (analyse_test)
    wander["retime"] = bool(wanders_beyond_a_sample(wander))
    return wander


def wanders_beyond_a_sample(wander: dict | None) -> bool:
    """The phase, counted in samples, wanders by more than a sample (at TIMING_FALSE_ALARM): a sample-index
    fit would smear the oscillation and report a sensitivity several per cent low."""
    return (wander is not None and wander["p_value"] < TIMING_FALSE_ALARM
            and wander["max_deviation_samples"] > 1.0)


def timing_refusal(source: str, wander: dict, why: str) -> CalibrationError:
    """The refusal of a record whose phase, counted in samples, wanders by more than a sample; ``why``: what
    was tried."""
    return CalibrationError(
        f"{source}: the sample count does not match the motion: samples were lost without a trace, or the "
        f"sample clock's rate wandered during the record. Counted in samples, the phase of the tangential "
        f"axis's oscillation wanders by up to {wander['max_deviation_samples']:.0f} sample periods "
        f"({wander['max_deviation_rad']:.2f} rad) between stretches of the record (chi-square "
        f"{wander['chi2']:.3g} for {wander['dof']} degrees of freedom) with no whole-sample step in it; {why}",
        "record the MEMS with its timestamps or its recorder's gap list (accelrig record keeps both) so the "
        "gaps can be placed, or re-record over a steady link; a clock that wanders (temperature) needs the "
        "timestamps too",
    )


# Sample jumps: a sample lost (or repeated) between two recorded ones moves the rest of the record by
# a whole sample period, so the residual of a whole-record sine fit steps by the signal's own change
# over one sample, m times for m samples.  Only where the signal is steep enough can a step be told
# from the noise: JUMP_VISIBLE (in sd of the residual differences) for a sample to be judged,
# JUMP_THRESHOLD for a difference to count as a step, JUMP_MATCH for it to match a whole number of
# samples.  White noise crosses 5 sd in about 6e-7 of the differences and must then also match a
# whole sample: far below one false step per record.
JUMP_VISIBLE = 10.0
JUMP_THRESHOLD = 5.0
JUMP_MATCH = 3.0


def sample_jumps(positions: np.ndarray, fit: SineFit) -> dict:
    """Steps of whole sample periods between consecutive recorded samples (lost or repeated samples).

    Works whatever the pattern of loss (scattered, in bursts or at a steady pace, which no phase
    or rate test can tell from a slow clock: a clock that runs slow spaces every sample alike, a
    record that drops every k-th sample does not).  ``fit`` is a whole-record sine fit at the
    record's own cycles per sample, at ``positions``.  Returns the steps found (with their size
    in samples), how many recorded samples were steep enough to judge, and an estimate of the
    samples lost or repeated over the whole record.
    """
    d = np.diff(fit.residuals)
    slope = np.diff(fit.fitted) / np.diff(positions)          # the signal's change over one sample
    scale = 1.4826 * float(np.median(np.abs(d - np.median(d))))
    out = {"judged_share": 0.0, "steps": 0, "samples_in_steps": 0, "lost": 0, "repeated": 0,
           "estimated_off_grid": 0.0, "difference_sd": scale}
    if not scale > 0:
        return out
    visible = np.abs(slope) > JUMP_VISIBLE * scale
    out["judged_share"] = float(np.mean(visible))
    if not visible.any():
        return out
    candidates = np.flatnonzero(visible & (np.abs(d) > JUMP_THRESHOLD * scale))
    # a step of m samples at k + 1 changes the residual by model(p + m) - model(p), p = positions[k + 1]
    sizes = np.zeros(candidates.size)
    p_next = positions[candidates + 1]
    first_guess = np.round(d[candidates] / slope[candidates])
    for m in (first_guess - 1, first_guess, first_guess + 1):
        expected = fit.model(p_next + m) - fit.model(p_next)
        match = (m != 0) & (sizes == 0) & (np.abs(d[candidates] - expected) < JUMP_MATCH * scale)
        sizes[match] = m[match]
    steps, sizes = candidates[sizes != 0], sizes[sizes != 0]
    # one bad sample (a spike) steps up and straight back down: not a lost sample
    spike = np.zeros(steps.size, dtype=bool)
    pair = (np.diff(steps) == 1) & (sizes[1:] == -sizes[:-1])
    spike[1:] |= pair
    spike[:-1] |= pair
    sizes = sizes[~spike]
    out["steps"] = int(sizes.size)
    out["samples_in_steps"] = int(np.sum(np.abs(sizes)))
    out["lost"] = int(np.sum(sizes[sizes > 0]))
    out["repeated"] = int(-np.sum(sizes[sizes < 0]))
    out["estimated_off_grid"] = float(out["samples_in_steps"] / out["judged_share"])
    return out


# encoder log times above this are UTC epoch seconds (after 2001-09-09), not seconds since a test's start
EPOCH_TIMES = 1e9


def overlapping_encoder(mems: Recording, encoder: EncoderLog, n: int, nominal_rate: float) -> EncoderLog:
    """The encoder log over the MEMS record (whose start is the only thing its clock is trusted for).

    A recording that carries UTC time (``accelrig record``) meets an encoder log timed in UTC epoch seconds (a
    lab logger's clock) on that clock: the log is moved onto the recording's time base."""
    origin = utc_origin(mems)
    if origin is not None and encoder.t[0] > EPOCH_TIMES:
        encoder = EncoderLog(encoder.t - origin, encoder.theta, encoder.ref, encoder.source)
    elif encoder.t[0] > EPOCH_TIMES:
        raise DataError(f"the encoder log's times are UTC epoch seconds ({encoder.t[0]:.3f} ..), and the MEMS "
                        "record carries no UTC time to meet them on",
                        "record the MEMS with 'accelrig record' (which writes its UTC start), or give the encoder "
                        "log's t in seconds from the MEMS record's first sample")
    mems_start = float(mems.t[0])
    mems_stop = mems_start + (n - 1) / nominal_rate
    overlap = min(mems_stop, encoder.t[-1]) - max(mems_start, encoder.t[0])
    if overlap <= 0:
        raise DataError(
            f"the encoder log ({encoder.t[0]:.3f} .. {encoder.t[-1]:.3f} s) and the MEMS record "
            f"({mems_start:.3f} .. {mems_stop:.3f} s) do not overlap in time",
            "record both during the same test, with times on one clock",
        )
    if overlap < 0.5 * (mems_stop - mems_start):
        raise DataError(
            f"the encoder log covers only {overlap:.2f} s of the {mems_stop - mems_start:.2f} s MEMS record",
            "record the encoder for the whole test",
        )
    return encoder.window(max(mems_start, encoder.t[0]), min(mems_stop, encoder.t[-1]))


@dataclass
class EncoderReference:
    """Stage 1's outcome: the encoder's sine fit and the reference accelerations with their budgets."""

    fit: SineFit
    frequency: float
    theta0: float
    u_theta0: float
    u_f_rel: float
    components: dict  # component -> {"value", "uncertainty", "relative_uncertainty", "budget"}


def encoder_step(theta: np.ndarray) -> float:
    """The quantisation step of an encoder log, rad: the smallest gap between the angles it takes; 0 when
    the angles are not on a grid (more distinct values than half the samples: interpolated or simulated).

    Gaps below 1e-7 of the swing are the same count written twice with different rounding."""
    levels = np.unique(theta)
    if levels.size < 3 or levels.size > theta.size / 2:
        return 0.0
    gaps = np.diff(levels)
    gaps = gaps[gaps > 1e-7 * (levels[-1] - levels[0])]
    return float(gaps.min()) if gaps.size else 0.0


def encoder_reference(enc: EncoderLog, frequency: float | None, setup: RotarySetup) -> EncoderReference:
    """Stage 1: f and theta0 from a sine fit of the encoder angle; eq. 3-4 give the reference accelerations."""
    if np.ptp(enc.theta) < 20 * setup.encoder_resolution:
        raise DataError(f"{enc.source or 'encoder'}: the angle hardly moves ({np.degrees(np.ptp(enc.theta)):.3f} deg)",
                        "is the bench running? is theta in radians?")
    peak = interpolated_dft_frequency(enc.t, enc.theta - enc.theta.mean())
    if frequency is not None and abs(peak / frequency - 1) > 0.02:
        raise DataError(f"excitation frequency {frequency:g} Hz not found in the encoder log: it oscillates at "
                        f"{peak:.3f} Hz", "fix --frequency or leave it out to estimate it from the encoder")
    enc_fit = fit_sine(enc.t, enc.theta, frequency=peak, harmonics=HARMONICS, fit_frequency=True)
    f = enc_fit.frequency
    if not enc_fit.converged:
        raise CalibrationError("the sine fit of the encoder angle did not converge", "check the encoder log")
    if enc_fit.amplitude[0] < max(enc_fit.amplitude[1:].max(initial=0.0), 10 * enc_fit.residual_sd):
        raise DataError(f"the encoder angle is not an oscillation at {f:.3f} Hz (harmonics or noise dominate)",
                        "check the encoder log and --frequency")
    theta0, u_theta0 = float(enc_fit.amplitude[0]), float(enc_fit.amplitude_uncertainty[0])
    u_f_rel = enc_fit.frequency_uncertainty / f
    omega = 2 * np.pi * f
    a_tan = setup.radius * omega**2 * theta0
    a_cen = setup.radius * (omega * theta0) ** 2 / 2.0
    u_r_rel = setup.radius_uncertainty / setup.radius
    # Encoder resolution: the quantisation error of a periodic angle sampled in step with
    # the motion repeats every period, so it does not average over periods as the fit's
    # white-noise covariance assumes.  Within a period, theta(t + T/2) = -theta(t) and
    # rounding is odd, so errors half a period apart are equal and opposite and add
    # alike on the fundamental: M samples per period give M / 2 independent errors and
    # an amplitude sd of (q / sqrt 12) sqrt(2 / (M / 2)).  (Simulated with M = 200: 17 ppm
    # predicted with M, 26 ppm seen, 24 ppm with M / 2.)  Conservative when not in step.
    # The step is the stated one or the one the log shows, whichever is coarser: a log quantised more
    # coarsely than stated (another encoder, a decimated count) must not keep the stated step's u.
    enc_rate = (enc.t.size - 1) / (enc.t[-1] - enc.t[0])
    independent_per_period = max(enc_rate / f / 2.0, 1.0)
    resolution = max(setup.encoder_resolution, encoder_step(enc.theta))
    u_quant = resolution / np.sqrt(12.0) * np.sqrt(2.0 / independent_per_period)
    resolution_note = (f"step {np.degrees(resolution):.3g} deg"
                       + (", read from the log (coarser than stated)" if resolution > setup.encoder_resolution else ""))
    components = {}
    for name, value, c_theta in (("tangential", a_tan, 1.0), ("centripetal", a_cen, 2.0), ("dc", a_cen, 2.0)):
        budget = UncertaintyBudget(
            [
                Contribution("radius", "u_r", u_r_rel),
                Contribution("bench geometry", "u_g", setup.geometry_uncertainty),
                Contribution("encoder amplitude (fit)", "u_theta0", u_theta0 / theta0, c_theta),
                Contribution("encoder resolution", "u_q", u_quant / theta0, c_theta, note=resolution_note),
                Contribution("frequency", "u_f", u_f_rel, 2.0),
            ],
            correlation=0.0, relative=True, value=value, unit="m/s^2",
        )
        components[name] = {"value": value, "uncertainty": budget.absolute(budget.combined),
                            "relative_uncertainty": budget.combined, "budget": budget.to_dict()}
    return EncoderReference(enc_fit, f, theta0, u_theta0, u_f_rel, components)


def excitation_on_tangential(y_t: np.ndarray, f: float, nominal_rate: float, axis: str, source: str) -> float:
    """The MEMS must show the excitation where expected: its cycles per sample on the tangential axis."""
    n = y_t.size
    nu_expected = f / nominal_rate
    if n < 8 or nu_expected * n < 3:
        raise DataError(f"{source}: {n} samples hold fewer than 3 periods of {f:.3f} Hz", "record longer")
    nu_peak = interpolated_dft_frequency(np.arange(n, dtype=float), y_t - y_t.mean())
    if abs(nu_peak / nu_expected - 1) > 0.1:
        seen = nu_peak * nominal_rate
        if abs(nu_peak / (2 * nu_expected) - 1) < 0.1:
            raise DataError(
                f"axis roles contradict the data: the 'tangential' axis {axis} carries mainly 2f "
                f"({seen:.2f} Hz), as a radial axis does",
                "swap --tangential and --radial, or check the mounting",
            )
        raise DataError(
            f"excitation frequency {f:.3f} Hz not found on the tangential axis {axis} of {source}: "
            f"its strongest line is at {seen:.3f} Hz (at the nominal rate {nominal_rate:g} Hz)",
            "check --tangential, --nominal-rate and that the encoder log belongs to this test",
        )
    return nu_peak


def sample_rate_by_fit(y_t: np.ndarray, nu_peak: float, f: float, u_f_rel: float, index: np.ndarray | None = None):
    """Stage 2 (fit): cycles per sample nu by a sample-index sine fit; fs = f / nu.  Returns (fit, nu, fs, u_fs).

    ``index``: each sample's position on the sample grid (gaps kept); default 0 .. n-1.  The
    residuals are checked for whiteness: correlated noise gets the sandwich covariance.
    """
    index = np.arange(y_t.size, dtype=float) if index is None else index
    rate_fit = fit_sine(index, y_t, frequency=nu_peak, harmonics=HARMONICS, fit_frequency=True, check_noise=True)
    if not rate_fit.converged:
        raise CalibrationError("the sample-index sine fit of the tangential axis did not converge")
    nu = rate_fit.frequency
    fs = f / nu
    u_fs = fs * float(np.sqrt((rate_fit.frequency_uncertainty / nu) ** 2 + u_f_rel**2))
    return rate_fit, nu, fs, u_fs


def filter_and_trim(counts: np.ndarray, i_t: int, f: float, fs: float, cutoff: float, nominal_rate: float,
                    source: str):
    """Stage 3: zero-phase low-pass at ``fs``, ends dropped for the filter to settle, then whole periods
    of the tangential axis.  Returns (sos, filtered, the whole-period slice, periods)."""
    n = counts.shape[0]
    sos = butterworth(fs, cutoff)
    filtered = signal.sosfiltfilt(sos, counts, axis=0)
    settle = int(np.ceil(SETTLE_SECONDS * fs))
    if n - 2 * settle < 4 * fs / f:
        raise DataError(f"{source}: {n / nominal_rate:.1f} s is too short", "record at least 5 s per test")
    first, last, periods = whole_periods(filtered[:, i_t], fs / f, settle, n - settle)
    return sos, filtered, slice(first, last), periods


def sample_rate_by_scan(counts, filtered, seg, i_t, f, nominal_rate, sos, cutoff):
    """Stage 2 (scan, the paper's): the rate from the filtered whole-period record; refiltered at that
    rate when it moved the cutoff.  Returns (fs, u_fs, nu, sos, filtered)."""
    fs, u_fs = scan_sample_rate(filtered[seg, i_t], f, nominal_rate)
    if abs(fs / nominal_rate - 1) > 1e-3:  # refilter at the scanned rate (the cutoff moves with fs)
        sos = butterworth(fs, cutoff)
        filtered = signal.sosfiltfilt(sos, counts, axis=0)
    return fs, u_fs, f / fs, sos, filtered


def axis_amplitudes(index, real, filtered, seg, f, fs, nu, rate_method, gain):
    """Stage 4: each axis's components at f, 2f and DC over the whole periods, filter gain corrected;
    their uncertainties from the same model fitted to the unfiltered record (see the module docstring),
    its residuals checked for whiteness.  ``index`` places the ``real`` samples on the sample grid
    of ``filtered`` (gaps kept: only real samples enter a fit; a record with gaps takes its
    amplitudes from the unfiltered fit).  Returns (amplitudes, raw fits)."""
    gapped = not np.array_equal(index, np.arange(index.size))   # gaps placed, or samples re-timed
    inside = (index >= seg.start) & (index < seg.stop)
    k_seg = index[inside]
    n_seg = seg.stop - seg.start
    bin_f = int(round(f * n_seg / fs))
    # the FFT reads the bin's frequency, m / N cycles per sample: its noise level is that of a fit there
    nu_amplitudes = nu if rate_method == "fit" else bin_f / n_seg
    amplitudes: dict[str, AxisAmplitudes] = {}
    raw_fits: dict[str, SineFit] = {}
    # one design matrix for the three raw axes (and, by the fit method, the three filtered ones)
    raw = fit_sines_known_frequency(k_seg, real[inside], nu_amplitudes, HARMONICS, check_noise=True)
    for axis in range(3):
        raw_fit = raw[axis]
        g_f, g_2f = gain["at_f"], gain["at_2f"]
        if gapped or rate_method == "fit":
            # the fit's own amplitudes: a three-parameter fit at f, 2f, 3f is already blind to the noise
            # a low-pass would remove, so it needs no filter (and no filter gain); bridged gaps would
            # leak through a filter into the amplitudes, the fit uses the real samples alone
            a1, a2, dc = raw_fit.amplitude[0], raw_fit.amplitude[1], raw_fit.offset
            g_f = g_2f = 1.0
        else:
            a1, a2, dc = _fft_components(filtered[seg, axis], bin_f)
        raw_fits[AXES[axis]] = raw_fit
        amplitudes[AXES[axis]] = AxisAmplitudes(
            at_f=float(a1 / g_f), at_f_uncertainty=float(raw_fit.amplitude_uncertainty[0] / g_f),
            at_2f=float(a2 / g_2f), at_2f_uncertainty=float(raw_fit.amplitude_uncertainty[1] / g_2f),
            dc=float(dc), dc_uncertainty=float(raw_fit.offset_uncertainty),
        )
    return amplitudes, raw_fits


def check_axis_roles(amplitudes: dict[str, AxisAmplitudes], i_t: int, i_r: int, f: float,
                     motion_2f_share: float = 0.0) -> None:
    """The tangential axis carries f and the radial 2f, more than any other axis: else say which axis does.

    ``motion_2f_share``: the tangential acceleration's 2f line over its f line that the encoder shows (a
    disk whose swing is not a pure sine: 4 theta_2 / theta_1).  That much of the tangential axis's 2f is
    its own; at small angles it can exceed the centripetal line, and is no sign of swapped axes."""
    amp_t, amp_r = amplitudes[AXES[i_t]], amplitudes[AXES[i_r]]
    at_2f = {a: amplitudes[a].at_2f for a in amplitudes}
    own = motion_2f_share * amp_t.at_f
    at_2f[AXES[i_t]] = max(amp_t.at_2f - own - 3.0 * amp_t.at_2f_uncertainty, 0.0)
    if amp_t.at_2f > amp_t.at_f:
        raise DataError(
            f"axis roles contradict the data: the 'tangential' axis {AXES[i_t]} carries more at 2f "
            f"({amp_t.at_2f:.0f} counts) than at f ({amp_t.at_f:.0f})",
            "check --tangential and --radial",
        )
    if amp_r.at_f > amp_r.at_2f:
        raise DataError(
            f"axis roles contradict the data: the 'radial' axis {AXES[i_r]} carries more at f "
            f"({amp_r.at_f:.0f} counts) than at 2f ({amp_r.at_2f:.0f})",
            "check --tangential and --radial",
        )
    strongest_f = max(amplitudes, key=lambda a: amplitudes[a].at_f)
    strongest_2f = max(at_2f, key=lambda a: at_2f[a])
    if strongest_f != AXES[i_t]:
        raise DataError(
            f"axis roles contradict the data: axis {strongest_f}, not the 'tangential' axis {AXES[i_t]}, carries "
            f"the {f:.3f} Hz motion", f"use --tangential {strongest_f}",
        )
    if strongest_2f != AXES[i_r]:
        raise DataError(
            f"axis roles contradict the data: axis {strongest_2f}, not the 'radial' axis {AXES[i_r]}, carries "
            f"the centripetal {2 * f:.3f} Hz", f"use --radial {strongest_2f}",
        )
    if amp_t.at_f < 10 * amp_t.at_f_uncertainty:
        raise DataError(f"the tangential axis {AXES[i_t]} shows no clear {f:.3f} Hz line", "check the recording")


def sensitivities(amplitudes: dict[str, AxisAmplitudes], reference: dict, i_t: int, i_r: int):
    """Stage 5: counts per m/s^2 (tangential axis from f, radial from 2f; the radial DC reported, not used),
    each with its budget: the output's noise, the reference's uncertainty and, for the radial axis, cross-talk.
    Returns (used, dc).

    Cross-talk: the radial axis also sees a share c of the tangential axis's force (cross-axis sensitivity,
    mounting).  At 2f that adds c times the tangential axis's own 2f line, which a motion that is not a pure
    sine puts there (a 2nd harmonic of 1 % gives the tangential axis 4 % of its f amplitude at 2f, as large as
    the whole centripetal line at small angles).  c is bounded by what the radial axis shows at f, where the
    tangential force is the only line (more when the motion adds its own f there: then conservative); the
    leak's phase is unknown, so its standard uncertainty is that bound over sqrt 2 (a cosine of a uniform
    phase).  Without a 2f line on the tangential axis the term is negligible."""
    def sens(axis: str, component: str, output: float, u_output: float, u_cross: float = 0.0) -> AxisSensitivity:
        ref = reference[component]
        value = output / ref["value"]
        u_noise = u_output / output
        u_ref = ref["relative_uncertainty"]
        return AxisSensitivity(axis, component, float(value),
                               float(abs(value) * np.sqrt(u_noise**2 + u_ref**2 + u_cross**2)),
                               float(output), float(ref["value"]), float(u_noise), float(u_ref), float(u_cross))

    amp_t, amp_r = amplitudes[AXES[i_t]], amplitudes[AXES[i_r]]
    coupling = amp_r.at_f / amp_t.at_f if amp_t.at_f > 0 else 0.0
    leak = coupling * amp_t.at_2f / np.sqrt(2.0)
    used = {
        AXES[i_t]: sens(AXES[i_t], "tangential", amp_t.at_f, amp_t.at_f_uncertainty),
        AXES[i_r]: sens(AXES[i_r], "centripetal", amp_r.at_2f, amp_r.at_2f_uncertainty,
                        leak / amp_r.at_2f if amp_r.at_2f > 0 else 0.0),
    }
    return used, sens(AXES[i_r], "dc", abs(amp_r.dc), amp_r.dc_uncertainty)


def _bland_altman_reference(enc: EncoderLog, enc_fit: SineFit, setup: RotarySetup) -> dict:
    """Encoder-derived tangential acceleration at the reference radius against the reference
    accelerometer, sample by sample on the encoder's clock (after the same low-pass)."""
    from accelrig.estimation.stats import bland_altman

    t = enc.t
    fs = (t.size - 1) / (t[-1] - t[0])
    omega = 2 * np.pi * enc_fit.frequency
    accel = np.zeros_like(t)
    for k in range(1, enc_fit.harmonics + 1):
        accel -= (k * omega) ** 2 * enc_fit.amplitude[k - 1] * np.cos(k * omega * t + enc_fit.phase[k - 1])
    accel *= setup.ref_radius
    ref = enc.ref
    if setup.filter_cutoff < fs / 2:
        ref = signal.sosfiltfilt(butterworth(fs, setup.filter_cutoff), ref)
    settle = int(np.ceil(SETTLE_SECONDS * fs))
    keep = slice(settle, t.size - settle)
    ba = bland_altman(ref[keep], accel[keep])
    out = ba.to_dict()
    out["compared"] = "reference accelerometer minus encoder tangential acceleration at ref_radius, m/s^2"
    out["ref_radius"] = setup.ref_radius
    return out


def load_test_inputs(mems_path: str | os.PathLike, encoder_path: str | os.PathLike | None, nominal_rate: float,
                     units: str | None = None) -> tuple[Recording, EncoderLog | None]:
    """The MEMS recording (a file without ``t`` gets k / nominal_rate) and the encoder log, if given.
    ``units``: what the file's values are; None takes what the file declares, else counts (a bench logger's
    raw output; ``accelrig record`` declares m/s^2 and the counts scale, which ``mems_counts`` undoes)."""
    if units is not None:
        normalise_unit(units)
    mems = load_recording(mems_path, units=units, rate=nominal_rate, default_units="counts")
    return mems, (read_encoder_csv(encoder_path) if encoder_path else None)


def analyse_files(
    mems_path: str | os.PathLike,
    encoder_path: str | os.PathLike | None,
    tangential: str,
    radial: str,
    nominal_rate: float,
    frequency: float | None = None,
    rate_method: str = "fit",
    setup: RotarySetup | None = None,
    units: str | None = None,
) -> RotaryTest:
    """Load the MEMS recording and the encoder log (``load_test_inputs``), then ``analyse_test``."""
    mems, encoder = load_test_inputs(mems_path, encoder_path, nominal_rate, units)
    return analyse_test(mems, encoder, tangential, radial, nominal_rate, frequency, rate_method, setup)
