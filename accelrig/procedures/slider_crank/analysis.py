"""Slider-crank dynamic verification (paper 000, sections 4-5).

A statically calibrated sensor rides the slider of a crank mechanism driven
at a series of motor speed steps.  Per step:

1. principal component analysis of the (calibrated) three axes gives the axis
   of motion and the acceleration along it;
2. an interpolated DFT gives the start frequency (the bare FFT peak is kept
   beside it: on a 1 s record its error reaches half a 1 Hz bin);
3. a four-parameter sine fit by variable projection on the timestamps, with
   harmonics sharing the frequency (the slider's second harmonic is about
   lambda times the first; a one-sine fit would be biased by tens of CRBs);
4. against the exact kinematics: x(phi) = r cos phi + sqrt(l^2 - r^2 sin^2 phi)
   has r cos phi as its *exact* first harmonic (the root holds only even
   harmonics), so at constant speed the first harmonic of the acceleration is
   exactly r omega^2 and the crank radius follows from the measured motion as
   r = A_1 / omega^2 (the double integration of the first harmonic, eq. 53-55);
5. backlash: play is taken up twice per turn, phase-locked to the crank (at
   the dead centres when the rail's friction dominates the slider's inertia,
   later, up to mid-stroke, where the force through the link reverses when
   inertia dominates), so the fit's residuals folded by crank angle keep the
   take-ups while the noise averages out; a significant folded residual
   concentrated at two places half a turn apart is reported as backlash;
6. motor: a step whose speed wanders within the record (frequency fitted on
   segments disagrees beyond their uncertainties), falls short of the
   commanded speed, or does not rise above the step before marks the roll-off.

Over all steps: a link or mounting that flexes (the 2nd harmonic growing
with speed against the 1st, where a rigid crank keeps both fixed: named with
its resonance, each radius corrected to zero speed, check_compliance), the
frequency response (measured first harmonic against
r omega^2 and its clearance bounds, paper Fig. 7), the radius per step
against the caliper radius +- clearance (Fig. 8) and their weighted mean,
and the verdict: does the static calibration hold under motion?
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import optimize, stats

from accelrig.errors import CalibrationError, DataError
from accelrig.estimation.crb import propagate_covariance
from accelrig.estimation.distributions import student_t_quantile
from accelrig.estimation.gum import COVERAGE_PROBABILITY, coverage_factor
from accelrig.estimation.residuals import (
    PooledNoise,
    Whiteness,
    ar_sandwich_covariance,
    band_variance_shares,
    checked_covariance,
    difference_noise_variance,
    lack_of_fit,
    pooled_noise_model,
    satterthwaite_dof,
)
from accelrig.estimation.sinefit import MIN_CYCLES, SineFit, fit_sine, interpolated_dft_frequency
from accelrig.estimation.stats import robust_sd
from accelrig.procedures.slider_crank.motion_fit import CrankMotionFit, fit_crank_motion
from accelrig.procedures.slider_crank.settings import DEFAULT_HARMONICS
from accelrig.recording import Recording, count_scale
from accelrig.result import CalibrationResult, Correction, Estimate, format_value
from accelrig.units import saturated

MIN_STEP_SAMPLES = 64
# A step is "short of its command" when the crank turns this much slower than commanded.
SPEED_SHORTFALL = 0.02
# Significance for the backlash and unsteady-speed tests (false alarm rate per step).
FALSE_ALARM = 1e-6
# Backlash must also be concentrated at the dead centres: folded residual power
# per bin near them at least this many times the power elsewhere.
KNOCK_CONCENTRATION = 4.0
# A neighbour check flags a step whose frequency is off the line through its
# neighbours by more than this many typical step spacings.
NEIGHBOUR_FACTOR = 3.0
# A step must hold crank motion: its first harmonic at least this many times its own
# uncertainty (a still sensor gives a "fit" of the noise at a few u), and at least
# MIN_STEP_CYCLES cycles of the *fitted* frequency (a static recording with pose changes
# fits a slow "sine" whose start frequency passed the 1.5-cycle check).  2 cycles, not
# more: the paper's own first step, 2.5 Hz for 1 s, must pass.
MIN_AMPLITUDE_SNR = 10.0
# A speed profile that moves by less than this share of the mean speed is "steady" (a record's
# tiny drift is followed by the fit but is not worth a warning).
SPEED_SPREAD = 0.005
# Residual rms over the model-free noise (white residuals only): above LOF_WARN the step carries a
# warning (u already includes the misfit, being from the residuals); above LOF_REFUSE the motion is
# not a crank's and the step is refused.
LOF_WARN = 1.15
LOF_REFUSE = 4.0
MIN_STEP_CYCLES = 2.0
# A steady step counts against a faster step's wandering being the drive's own (mark_rolloff) when the same
# ripple would have left sidebands this many times its u(A_1) (the speed-profile F test at 1e-3 over a dozen
# terms needs about that).
RIPPLE_VISIBLE = 5.0
# A link or a mounting with a spring amplifies the crank's harmonic n by 1 / (1 - n^2 c omega^2), c = 1 / omega_r^2:
# the displacement's 2nd harmonic grows against the 1st with speed, where a rigid crank keeps both fixed by its
# geometry (play adds odd harmonics only).  The trend is judged over the steps at this false-alarm rate
# (check_compliance); beyond COMPLIANCE_REFUSE (the 2nd harmonic amplified by a third: a resonance below 4 times the
# fastest step) the one-resonance correction is not trusted and the verification is refused.
COMPLIANCE_ALPHA = 1e-3
COMPLIANCE_REFUSE = 0.25
MIN_COMPLIANCE_STEPS = 3
# A phase-locked event at the dead centres is the flexing link ringing, not play (_is_link_ringing), when the
# compliance its own ring frequency implies, c = 1 / (2 pi f_ring)^2, agrees with the harmonics' trend within this
# many times their combined u: a spring rings at its own resonance, a contact with play at the contact's.
RING_AGREE = 3.0
# ... and only when every flagged step rings within this share of their median: a spring rings at one frequency at
# every speed (held-out links: 299-301 Hz, 449-454 Hz); a take-up's own shape (a dwell, a free flight) has no one
# frequency, and its spectrum's peak moves with speed (the project simulator's 50 um dwell: 66-174 Hz)
RING_SPREAD = 0.05
# ... and, where the trend cannot rule out a rigid link (c below RING_AGREE times the combined u: a 450 Hz link's
# trend sits 0.8-4.7 u from zero over 5 steps at 3-10 Hz, so a trend alone cannot tell it from a rigid link whose
# play knocks at one contact frequency), only when the ring does not grow with speed: the rail's friction steps by
# the same force at every speed (at the dead centres the rod lies along the rail, so the normal load is the
# slider's weight and its preload), so a link's ring keeps its size (amplitude ~ f^0: held-out links 0.06-0.35),
# while play's knock is an impact whose closing speed grows with the crank's (~ f^1 or faster: the project
# simulator's dwell 1.7-1.9, held-out play taken up at the dead centres of a braked slider 0.9-1.2).  The exponent
# of the knock's size against the step's speed is judged against the midpoint of the two laws.
RING_GROWTH = 0.5
# ... or, where it grows, when it keeps its timing against the dead centres: a rail whose friction turns over a broad
# band of speed (a greased or polymer slide, tens of mm/s) reverses too slowly at the slow steps to ring the link fully,
# so a link's ring can grow with speed too (held-out 450 Hz link, friction turning over 10 mm/s: g 1.3-1.5).  Its force
# reverses symmetrically about the moment the velocity does, so its ring keeps one phase against the dead centre at
# every speed (measured 160-174 deg over 4.5-10 Hz); play's knock comes after the pin has crossed the gap, a fixed
# crank angle (sqrt(2 play / r) for a slider held by its friction), i.e. later in time at slower steps, and its
# phase at the ring frequency moves by f_ring times that delay (held-out braked slide, 10 um: hundreds of degrees).
# The phases are judged as one at this false-alarm rate (ring_keeps_timing).
RING_TIMING_ALPHA = 1e-3
# A link named by its ring corrects the radii by its resonance even where the trend could not show it
# (compliance_with_ring): the ring's c_ring = 1 / (2 pi f_ring)^2 carries this relative u for what a ring is, a damped
# one running at sqrt(1 - zeta^2) of the resonance that amplifies the harmonics (a spring-damper link amplifies them
# by 1 + (f / f_r)^2 whatever its damping, to that order): c_ring high by zeta^2, 5 % at zeta 0.22; a ring that still
# shows after 2.5 of its cycles (ring_frequency) is damped less
RING_RESONANCE_U = 0.05
# ... or, where its timing moves, when its lost motion is too small for play waiting at the dead centres: play is
# crossed there only where the rail's friction outweighs the slider's inertia (else the force through the link reverses
# elsewhere and the knock comes later), and the contact that then takes it up, ringing at f_ring with the slider's mass,
# gives way by that friction over its stiffness each way, so play there loses at least 2 A_1 (1 - lambda) / (2 pi
# f_ring)^2.  A link on a rail whose friction turns over sharply (a few mm/s) and holds 1.5 times its sliding value at
# rest sticks at each dead centre until the stretched link breaks it free: a fixed crank angle after the dead centre
# like play, but losing only the friction over the link's stiffness (held-out 450 Hz link: 0.1-2 um, 0.03-0.13 of that
# bound at 10 Hz; braked play 1.7-5.7 of it).  Judged per flagged step, one-sided, at RING_TIMING_ALPHA over the steps
# (lost_motion_below_hold).
# A dead-centre event counts as mirrored (odd harmonics only, _mirrored) when the power of its part that repeats
# half a turn on is below this share of the power of its part that flips.
MIRROR_SHARE = 0.1
# A motor whose torque ripples N times per turn (cogging; a gear's or a belt's teeth) modulates the crank angle at N
# times the crank's rate: lines at (N +- 1) f in the residuals above the fitted harmonics (name_crank_locked_ripple).
# The pair is looked for at FALSE_ALARM over the multiples and steps tried, and named when at least this many steps
# agree on N and the pair holds at least CRANK_LOCKED_SHARE of the crank-locked lines' excess power (play's knocks
# put a comb of odd harmonics there, which no single pair holds).
CRANK_LOCKED_STEPS = 2
CRANK_LOCKED_SHARE = 0.5
# A step's radius is flagged outside the caliper radius +- clearance by a test at this family-wise level
# over the steps judged (Sidak: each step at 1 - (1 - alpha)^(1/m)): with five sound steps at k = 2 one
# falls outside by chance in a fifth of runs, a warning an operator would learn to ignore.
CLEARANCE_ALPHA = 0.05
# One AR model of all steps' residuals is kept unless a test rejects it at this level (pool_noise): a wrong
# smooth model halves a slow step's u under 1/f noise, the pooled bands only make it scatter, so the test
# errs towards the bands.
POOL_AR_ALPHA = 0.05
# A step's own u is judged against the pooled bands at its own speed at this family-wise level (_judge_own_u):
# the shortfall it is for is large (a 2.5 Hz step's own u at half the bands' under 1/f: p ~ 1e-9), and every
# false alarm costs a white run a warning, so it is stricter than the AR test
OWN_U_ALPHA = 0.01


def step_name(index: int, label: str) -> str:
    """How every message names a step: 1-based, as the operator counts ("step 2 (run.csv)"); a live step's
    label is already "step N"."""
    return label if label.startswith("step ") else f"step {index + 1} ({label})"


def clearance_k(steps_judged: int, dof: float = float("inf")) -> float:
    """Coverage factor of the per-step clearance test: two-sided, family-wise CLEARANCE_ALPHA over the steps,
    Student's t on the effective dof of the step's u (the normal quantile at infinite dof)."""
    per_step = 1.0 - (1.0 - CLEARANCE_ALPHA) ** (1.0 / max(steps_judged, 1))
    if not np.isfinite(dof):
        return float(stats.norm.isf(per_step / 2))
    return float(student_t_quantile(1.0 - per_step / 2, max(dof, 1.0)))


def dof_with_play(u: float, u_play: float, dof: float) -> float:
    """Welch-Satterthwaite for u^2 = u_noise^2 + u_play^2, the play's Type B term known exactly (infinite dof)."""
    u_noise2 = max(u**2 - u_play**2, 0.0)
    if u_noise2 <= 0 or not np.isfinite(dof):
        return float("inf")
    return float(u**4 / (u_noise2**2 / dof))


def outside_clearance(radius: Estimate, crank_radius: float, clearance: float, k: float) -> bool:
    """|r - r_caliper| beyond the clearance by more than k u(r)."""
    return bool(abs(radius.value - crank_radius) > clearance + k * radius.uncertainty)


@dataclass
class StepResult:
    """One motor speed step, analysed."""

    index: int
    label: str
    n_samples: int
    commanded_hz: float | None
    frequency_hz: Estimate
    fft_peak_hz: float
    start_frequency_hz: float
    amplitude: Estimate            # first harmonic of the acceleration along the axis of motion
    harmonic_amplitudes: Estimate  # all fitted harmonics, m/s^2
    peak: Estimate                 # peak of the fitted waveform (the TDC peak)
    model_amplitude: float         # r omega^2 at the measured speed, caliper radius
    model_amplitude_bounds: tuple[float, float]
    model_peak: float              # r omega^2 (1 + lambda)
    model_amplitude_commanded: float | None
    ratio: Estimate                # measured / model first harmonic
    radius_m: Estimate
    within_clearance: bool
    backlash: bool
    play_m: float                  # play estimated from the odd harmonics when backlash is seen (0 otherwise)
    radius_play_uncertainty_m: float  # the play's share of u(radius), common to all steps
    knock_peak: float              # largest phase-locked residual near a dead centre, m/s^2
    knock_significance: float      # chi-square p-value of the folded residuals where the play is taken up
    take_up_deg: float             # where: crank angle after each dead centre (0: at them)
    speed_unsteady: bool
    speed_spread_hz: float
    motor_limited: bool = False
    speed_ripple_hz: float = 0.0   # rate of the speed profile's swings (half its sign changes per second)
    # a compliant link or mounting (check_compliance): the radius's correction factor 1 - c omega^2 applied and
    # its share of u(radius) (common to all steps); a dead-centre event that is the link ringing, not play
    compliance_factor: float = 1.0
    radius_compliance_uncertainty_m: float = 0.0
    link_ringing: bool = False
    ring_hz: float = float("nan")  # the frequency a link_ringing step's event rings at (ring_frequency)
    # a speed ripple locked to the crank (name_crank_locked_ripple): N per turn (0: none seen) and its relative peak size
    crank_locked_per_turn: int = 0
    crank_locked_ripple: float = 0.0
    # a speed ripple the faster steps followed but this step could not (budget_unfollowed_ripple): its sidebands'
    # share of u(radius), u(speed) and of the 2nd harmonic (relative), added as Type B terms
    ripple_radius_uncertainty_m: float = 0.0
    ripple_frequency_uncertainty_hz: float = 0.0
    ripple_second_harmonic_share: float = 0.0
    axis: list[float] = field(default_factory=list)
    axis_angles_deg: list[float] = field(default_factory=list)
    axis_angle_uncertainty_deg: float = 0.0
    residual_sd: float = 0.0
    noise_sd: float = 0.0
    n_iterations: int = 0
    fit: SineFit | None = None
    harmonics: int = DEFAULT_HARMONICS  # fitted (fewer when the rate leaves no room below Nyquist)
    speed_order: int = 1           # order of the crank-angle profile fitted (1: constant speed)
    residual_checks: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)  # what the residual checks found, for the warnings
    clearance_k: float = 0.0       # the coverage factor within_clearance was judged at
    # effective degrees of freedom of u^2 (GUM G.4) and the coverage factor k = t_p(nu) of the expanded
    # uncertainty U = k u at 95.45 % (2 at large dof): what the verdict and the clearance test judge with
    radius_dof: float = float("inf")
    radius_k: float = 2.0
    frequency_dof: float = float("inf")
    frequency_k: float = 2.0
    state: StepFit | None = field(default=None, repr=False)      # the fits, for pool_noise
    checks: ResidualChecks | None = field(default=None, repr=False)

    @property
    def where(self) -> str:
        return step_name(self.index, self.label)

    def to_json_dict(self) -> dict:
        return {
            "index": self.index,
            "label": self.label,
            "n_samples": self.n_samples,
            "commanded_hz": self.commanded_hz,
            "frequency_hz": self.frequency_hz.to_dict(),
            "fft_peak_hz": self.fft_peak_hz,
            "start_frequency_hz": self.start_frequency_hz,
            "amplitude": self.amplitude.to_dict(),
            "harmonic_amplitudes": self.harmonic_amplitudes.to_dict(),
            "peak": self.peak.to_dict(),
            "model_amplitude": self.model_amplitude,
            "model_amplitude_bounds": list(self.model_amplitude_bounds),
            "model_peak": self.model_peak,
            "model_amplitude_commanded": self.model_amplitude_commanded,
            "ratio": self.ratio.to_dict(),
            "radius_m": self.radius_m.to_dict(),
            "within_clearance": self.within_clearance,
            "clearance_k": self.clearance_k,
            "radius_dof": _plain_dof(self.radius_dof),
            "radius_k": self.radius_k,
            "frequency_dof": _plain_dof(self.frequency_dof),
            "frequency_k": self.frequency_k,
            "backlash": self.backlash,
            "play_m": self.play_m,
            "radius_play_uncertainty_m": self.radius_play_uncertainty_m,
            "knock_peak": self.knock_peak,
            "knock_significance": self.knock_significance,
            "take_up_deg": self.take_up_deg,
            "speed_unsteady": self.speed_unsteady,
            "speed_spread_hz": self.speed_spread_hz,
            "speed_ripple_hz": self.speed_ripple_hz,
            "compliance_factor": self.compliance_factor,
            "radius_compliance_uncertainty_m": self.radius_compliance_uncertainty_m,
            "link_ringing": self.link_ringing,
            "ring_hz": self.ring_hz if np.isfinite(self.ring_hz) else None,
            "crank_locked_per_turn": self.crank_locked_per_turn,
            "crank_locked_ripple": self.crank_locked_ripple,
            "ripple_radius_uncertainty_m": self.ripple_radius_uncertainty_m,
            "ripple_frequency_uncertainty_hz": self.ripple_frequency_uncertainty_hz,
            "motor_limited": self.motor_limited,
            "axis": self.axis,
            "axis_angles_deg": self.axis_angles_deg,
            "axis_angle_uncertainty_deg": self.axis_angle_uncertainty_deg,
            "residual_sd": self.residual_sd,
            "noise_sd": self.noise_sd,
            "n_iterations": self.n_iterations,
            "harmonics": self.harmonics,
            "speed_order": self.speed_order,
            "residual_checks": self.residual_checks,
        }


def _plain_dof(dof: float) -> float | None:
    """A dof for JSON: None when infinite (JSON has no infinity)."""
    return float(dof) if np.isfinite(dof) else None


# ---------------------------------------------------------------- building blocks

def check_geometry(crank_radius: float, rod_length: float, clearance: float) -> None:
    if not (np.isfinite(crank_radius) and crank_radius > 0):
        raise DataError(f"crank radius {crank_radius} m must be positive", "give it in metres, e.g. 0.00635")
    if not (np.isfinite(rod_length) and rod_length > crank_radius):
        raise DataError(f"rod length {rod_length} m must exceed the crank radius {crank_radius} m")
    if not (np.isfinite(clearance) and 0 <= clearance < crank_radius):
        raise DataError(f"clearance {clearance} m must be >= 0 and below the crank radius")


def principal_axis(acc: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Axis of motion by PCA: (unit axis, signal along it, first-order sd of the axis angle, rad).

    The axis is signed so its largest component is positive.  Angle sd from
    eigenvector perturbation: sigma_perp / (s sqrt(n)), s the motion's rms.
    """
    centred = acc - acc.mean(axis=0)
    cov = centred.T @ centred / acc.shape[0]
    values, vectors = np.linalg.eigh(cov)
    axis = vectors[:, -1]
    axis = axis * np.sign(axis[np.argmax(np.abs(axis))])
    if np.sqrt(max(values[-1], 0.0)) <= 1e-9 * (1.0 + float(np.abs(acc.mean(axis=0)).max())):
        raise DataError("the sensor did not move: all three axes are constant")
    perp = max(float(values[:2].mean()), 0.0)
    angle_sd = float(np.sqrt(perp * (values[-1] + perp) / (acc.shape[0] * values[-1] ** 2)))
    return axis, acc @ axis, angle_sd


def clipped_samples(rec: Recording) -> int:
    """Samples at the sensor's full scale (any axis); ``rec`` raw, in m/s^2 (before any correction)."""
    acc = rec.acc
    scale = count_scale(rec.meta)
    if scale is not None:
        return int(np.count_nonzero(np.any(saturated(acc, scale), axis=1)))
    # No declared full scale: flat tops (three or more consecutive samples at an axis's extreme).
    flat = 0
    for column in acc.T:
        if column.max() == column.min():
            continue  # a constant axis (e.g. one the file does not carry) is not clipped
        for extreme in (column.max(), column.min()):
            at = np.isclose(column, extreme, rtol=1e-9, atol=0.0)
            runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], at.astype(int), [0]]))))[::2]
            flat += int(runs[runs >= 3].sum()) if runs.size else 0
    return flat


def robust_noise_sd(residuals: np.ndarray) -> float:
    """Noise sd from first differences, median-based so knocks and rare spikes do not inflate it."""
    d = np.diff(residuals)
    return float(robust_sd(d) / np.sqrt(2))


def fold_residuals(t, residuals, frequency, phase1, samples_per_bin: float = 2.0):
    """Residuals averaged in bins of crank angle (phase-locked content survives, noise averages out).

    ``samples_per_bin`` is per cycle (2: a knock's ring at ~100 Hz is still
    resolved at 2 kHz).  Returns (bin centres in rad of the first-harmonic
    phase, bin means, counts).
    """
    samples_per_cycle = residuals.size / max(frequency * (t[-1] - t[0]), 1e-12)
    n_bins = int(np.clip(samples_per_cycle // samples_per_bin, 8, 4096))
    theta = np.mod(2 * np.pi * frequency * t + phase1, 2 * np.pi)
    idx = np.minimum((theta / (2 * np.pi) * n_bins).astype(int), n_bins - 1)
    counts = np.bincount(idx, minlength=n_bins)
    sums = np.bincount(idx, weights=residuals, minlength=n_bins)
    means = np.where(counts > 0, sums / np.maximum(counts, 1), 0.0)
    centres = (np.arange(n_bins) + 0.5) * 2 * np.pi / n_bins
    return centres, means, counts


def _phase_locked_template(t, residuals, frequency, phase1):
    """The residuals' crank-angle-folded mean at each sample, and the number of bins it used."""
    centres, means, counts = fold_residuals(t, residuals, frequency, phase1, samples_per_bin=1.0)
    theta = np.mod(2 * np.pi * frequency * t + phase1, 2 * np.pi)
    filled = counts > 0
    # interpolated between bin centres, not a staircase: a take-up sharper than a bin moves within its bin
    # from cycle to cycle, and a staircase leaves that in the residuals
    return np.interp(theta, centres[filled], means[filled], period=2 * np.pi), int(np.count_nonzero(counts))


def _noise_only_covariance(t, fit: SineFit, take_up: float = 0.0) -> SineFit:
    """The fit with its covariance scaled to the random noise alone, for a record with knocks.

    Knocks are deterministic and phase-locked: left in the residual sd they
    would inflate every uncertainty several times over, yet they are not noise.
    Their effect on the first harmonic is a systematic, budgeted separately
    (the play term of the radius uncertainty).  The noise is what remains of
    the residuals after removing their crank-angle-folded mean (one sample per
    cycle per bin: the template follows even a fast ring; the degrees of
    freedom it takes are subtracted).
    """
    template, bins = _phase_locked_template(t, fit.residuals, fit.frequency, float(fit.phase[0]))
    cleaned = fit.residuals - template
    dof = cleaned.size - fit.covariance.shape[0] - bins
    if dof <= 0:
        return fit
    share = quiet_noise_share(t, cleaned, fit.frequency, float(fit.phase[0]), take_up)
    scale = float(np.sqrt(share * (cleaned @ cleaned) / dof)) / fit.residual_sd
    if not np.isfinite(scale) or scale >= 1:
        return fit
    return replace(
        fit,
        covariance=fit.covariance * scale**2,
        frequency_uncertainty=fit.frequency_uncertainty * scale,
        amplitude_uncertainty=fit.amplitude_uncertainty * scale,
        phase_uncertainty=fit.phase_uncertainty * scale,
        offset_uncertainty=fit.offset_uncertainty * scale,
    )


def dead_centre_window(theta: np.ndarray, frequency: float, take_up: float = 0.0) -> np.ndarray:
    """Crank angles (first-harmonic phase, rad) near where play is taken up, ``take_up`` rad after each dead centre.

    The first harmonic A cos(theta) has its extremes, the dead centres, at
    theta = 0 and pi.  A take-up starts there (``take_up`` 0) or, when the
    slider's inertia outweighs the rail's friction, later, where the force
    through the link reverses; it rings for some ms: the window is from 2 % of a
    cycle before to min(25 % of a cycle, 30 ms) after each take-up.
    """
    after = min(0.25, 0.030 * frequency) * 2 * np.pi
    before = 0.02 * 2 * np.pi
    near = np.zeros(np.shape(theta), dtype=bool)
    for dead_centre in (take_up, take_up + np.pi):
        delta = np.angle(np.exp(1j * (np.asarray(theta) - dead_centre)))
        near |= (delta >= -before) & (delta <= after)
    return near


def quiet_noise_share(t, cleaned, frequency, phase1, take_up: float = 0.0) -> float:
    """Noise variance away from the dead centres over the variance of all ``cleaned`` residuals, at most 1.

    With play, the residuals minus their crank-angle-folded mean still hold what the fold cannot follow
    (a take-up sharper than a sample shifts from cycle to cycle within its bin): at 10 Hz with 50 um of
    play, 13 times the noise sd, all of it at the dead centres.  It is deterministic, not noise: the
    part of the cycle away from them measures the noise (white or coloured, its marginal variance).
    """
    theta = np.mod(2 * np.pi * frequency * t + phase1, 2 * np.pi)
    quiet = ~dead_centre_window(theta, frequency, take_up)
    total = float(cleaned @ cleaned)
    if quiet.sum() < 0.2 * cleaned.size or total <= 0:
        return 1.0
    return float(min((cleaned[quiet] @ cleaned[quiet]) / quiet.sum() / (total / cleaned.size), 1.0))


def detect_backlash(t, residuals, frequency, phase1, noise_sd):
    """Play taken up twice per turn: (detected, peak phase-locked residual, p-value, take-up angle in rad).

    A pin with play is crossed whenever the force through the link reverses: at the dead centres when the
    rail's friction outweighs the slider's inertia (a slow step, a stiff slide), up to a quarter turn later
    when inertia dominates (the force follows the acceleration, which reverses near mid-stroke).  So the
    take-up is looked for at the dead centres first (FALSE_ALARM), then at every other angle, a pair of
    windows (``dead_centre_window``) half a turn apart, at FALSE_ALARM over the number of angles tried: a
    significant folded residual there, KNOCK_CONCENTRATION times stronger than elsewhere.
    """
    centres, means, counts = fold_residuals(t, residuals, frequency, phase1)
    if noise_sd <= 0:
        return False, 0.0, 1.0, 0.0
    z2 = counts * means**2 / noise_sd**2  # chi-square(1) per bin under noise alone
    n_bins = centres.size
    angles = 2 * np.pi * np.arange(n_bins // 2) / n_bins   # the dead centres (0), then one bin apart
    # Away from the dead centres the search looks only at what is sharper than the fitted harmonics: a
    # speed that wanders leaves a smooth fold (its low harmonics) peaking a quarter turn from them, a
    # take-up is a step or an impact, broadband.  (4 harmonics and the mean, least squares over the bins.)
    # And against what is not phase-locked (the scatter within the bins, when above the noise: a wandering
    # speed leaves it large and its fold uneven by chance), so a search over angles finds no chance peak.
    basis = np.column_stack([np.ones(n_bins)] + [f(k * centres) for k in range(1, 5) for f in (np.cos, np.sin)])
    weight = np.sqrt(counts)
    coef = np.linalg.lstsq(basis * weight[:, None], means * weight, rcond=None)[0]
    within = (float(residuals @ residuals) - float(np.sum(counts * means**2))) / max(residuals.size - n_bins, 1)
    sharp = counts * (means - basis @ coef) ** 2 / max(noise_sd**2, within)
    found = []
    for k, take_up in enumerate(angles):
        near = dead_centre_window(centres, frequency, take_up)
        if near.sum() == 0 or (~near).sum() == 0:
            continue
        score = z2 if k == 0 else sharp
        p_value = float(stats.chi2.sf(score[near].sum(), int(near.sum())))
        concentration = score[near].mean() / max(score[~near].mean(), 1.0)
        level = FALSE_ALARM if k == 0 else FALSE_ALARM / max(angles.size - 1, 1)
        if k == 0 or (p_value < level and concentration > KNOCK_CONCENTRATION):
            found.append((p_value < level and concentration > KNOCK_CONCENTRATION, -score[near].sum(), k, p_value,
                          float(np.max(np.abs(means[near]))), float(take_up)))
        if k == 0 and found[0][0]:
            break   # at the dead centres: the play's usual place, and the test of before
    if not found:
        return False, 0.0, 1.0, 0.0
    best = found[0] if found[0][0] or len(found) == 1 else min(found[1:])
    detected, _, k, p_value, peak, take_up = best
    if detected and k > 0:
        # every window holding the whole ring scores alike: the take-up is where the pair's folded power peaks
        near = dead_centre_window(centres, frequency, take_up)
        pair = sharp + np.roll(sharp, -(n_bins // 2))
        first = int(np.argmax(np.where(near, pair, -np.inf)))
        take_up = float(np.mod(2 * np.pi * first / n_bins, np.pi))
    return bool(detected), peak, p_value, take_up if detected else 0.0


@dataclass
class ResidualChecks:
    """What the step's residuals say (estimation.residuals) and the covariance that follows."""

    covariance: np.ndarray   # of the crank-motion parameters
    inflation: float         # factor on the sine fit's white-noise u (harmonic amplitudes, peak)
    method: str
    whiteness: dict
    lack_of_fit: dict | None
    notes: list[str]
    white: np.ndarray | None = None     # the white-noise covariance the inflation is against
    tested: Whiteness | None = None
    pooled: dict | None = None          # the noise spectrum pooled over the steps (pool_noise), when used
    dof: float = float("inf")           # effective dof of the covariance's estimate (n - p white, the sandwich's)
    # from the pooled bands (pool_noise): the radius's and the speed's dof, and what the combined radius needs
    pooled_dof: dict | None = None
    pooled_model: PooledNoise | None = field(default=None, repr=False)
    pooled_index: int = -1
    radius_shares: np.ndarray | None = field(default=None, repr=False)

    @property
    def correlated(self) -> bool:
        """The residuals were found correlated: u from a sandwich (what pool_noise revises)."""
        return self.tested is not None and self.tested.correlated

    def to_dict(self) -> dict:
        out = {"covariance_method": self.method, "inflation": self.inflation, "whiteness": self.whiteness,
               "lack_of_fit": self.lack_of_fit, "dof": _plain_dof(self.dof)}
        if self.pooled is not None:
            out["pooled_noise"] = self.pooled
        return out


def motion_checks(where: str, t, y, motion: CrankMotionFit, knocked: SineFit | None,
                  take_up: float = 0.0) -> ResidualChecks:
    """Whiteness and lack of fit of the crank-motion fit's residuals; the covariance they call for.

    White residuals: sigma^2 (J'J)^-1.  Correlated (estimation.residuals.checked_covariance): the
    batch-means sandwich, or, with too few blocks for it (a step of a second or two), the sandwich
    whose middle matrix comes from an AR model of the residual spectrum.  Lack of fit is judged
    only on white residuals (correlated noise makes the model-free variance too small): a warning
    above LOF_WARN, a refusal above LOF_REFUSE.  With backlash the knocks are phase-locked and not
    noise: their folded template is removed first.
    """
    resid = motion.residuals
    dof = resid.size - motion.n_parameters
    share = 1.0
    if knocked is not None:
        template, bins = _phase_locked_template(t, resid, knocked.frequency, float(knocked.phase[0]))
        resid = resid - template
        dof -= bins
        share = quiet_noise_share(t, resid, knocked.frequency, float(knocked.phase[0]), take_up)
    dof = max(dof, 1)
    sigma2 = share * float(resid @ resid) / dof
    normal = motion.jacobian.T @ motion.jacobian
    white = sigma2 * np.linalg.pinv(normal)
    cov, method, w, cov_dof = checked_covariance(motion.jacobian, resid, white, white_dof=dof)
    if share < 1.0 and w.correlated:
        cov = cov * share   # the sandwich's middle matrix held the take-up's leftover too
    notes: list[str] = []
    lof = None
    if w.correlated:
        notes.append(f"{where}: {w.describe()}; u from the {method}")
    else:
        noise_var, noise_dof = difference_noise_variance(y, order=3)
        result = lack_of_fit(sigma2, dof, noise_var, noise_dof)
        lof = result.to_dict()
        if result.significant() and result.ratio > LOF_REFUSE:
            raise CalibrationError(
                f"{where}: {result.describe()}: the slider's acceleration is not a crank's motion (even with the "
                f"speed followed to order {motion.order})",
                "check that the sensor rides the slider firmly, the stand runs freely and nothing else shakes it",
            )
        if result.significant() and result.ratio > LOF_WARN:
            notes.append(f"{where}: {result.describe()}; u is from the residuals, so it includes the misfit")
    return ResidualChecks(cov, _inflation(motion, cov, white), method, w.to_dict(), lof, notes, white, w,
                          dof=float(cov_dof))


def _inflation(motion: CrankMotionFit, cov: np.ndarray, white: np.ndarray) -> float:
    """The radius's u over its white-noise u, at least 1: the factor on the sine fit's u (harmonics, peak)."""
    _, g = motion.radius_gradient()
    return float(np.sqrt(max((g @ cov @ g) / (g @ white @ g), 1.0))) if g @ white @ g > 0 else 1.0


def fft_peak_frequency(t, y) -> float:
    """The bare FFT arg-max (what the paper started from), for comparison only."""
    n = y.size
    dt = (t[-1] - t[0]) / (n - 1)
    spectrum = np.abs(np.fft.rfft(y - y.mean()))
    return (int(np.argmax(spectrum[1:])) + 1) / (n * dt)


def _peak_of_waveform(amps_phases: np.ndarray, harmonics: int) -> float:
    """Largest |sum_k A_k cos(k theta + phi_k)| over a cycle (the fitted waveform's peak)."""
    theta = np.linspace(0, 2 * np.pi, 1441)
    wave = np.zeros_like(theta)
    for k in range(harmonics):
        wave += amps_phases[2 * k] * np.cos((k + 1) * theta + amps_phases[2 * k + 1])
    return float(np.max(np.abs(wave)))


# A step's first harmonic against the crank's r w^2 at the speed measured: a sensitivity error, even a profile
# for another range (a factor 4), stays within this factor; beyond it the record is not this crank's motion (a
# still or hand-turned record fits a slow "sine" from gravity turning; or the radius or the axis is wrong), and
# a verdict on it would blame the motor or the clearance for what is not there.
MOTION_RATIO = 8.0


def check_crank_motion(where: str, fit: SineFit, t: np.ndarray, crank_radius: float) -> None:
    """Refuse a step with no crank motion in it (a still or static recording given as a step), or with a
    motion that is not this crank's (its first harmonic far from r w^2: see MOTION_RATIO)."""
    amp1, u_amp1 = float(fit.amplitude[0]), float(fit.amplitude_uncertainty[0])
    if not amp1 >= MIN_AMPLITUDE_SNR * u_amp1:
        raise DataError(
            f"{where}: no crank motion: the first harmonic {amp1:.3g} +- {u_amp1:.2g} m/s^2 at {fit.frequency:.4g} Hz "
            f"is not clearly above the noise (needs {MIN_AMPLITUDE_SNR:g} u)",
            "record while the crank turns steadily at the step's speed",
        )
    span = t[-1] - t[0] + (t[-1] - t[0]) / (t.size - 1)
    cycles = fit.frequency * span
    if cycles < MIN_STEP_CYCLES:
        raise DataError(
            f"{where}: no steady crank motion: the record holds only {cycles:.2f} cycles of the fitted "
            f"{fit.frequency:.4g} Hz (needs {MIN_STEP_CYCLES:g})",
            "record at least 2 (better 3) crank turns per step while the crank turns steadily",
        )
    expected = crank_radius * (2 * np.pi * fit.frequency) ** 2   # the first harmonic of x'' (any rod length)
    if not 1 / MOTION_RATIO <= amp1 / expected <= MOTION_RATIO:
        raise DataError(
            f"{where}: not the motion of a {1e3 * crank_radius:g} mm crank: the first harmonic along the slider is "
            f"{amp1:.3g} m/s^2 at {fit.frequency:.3g} Hz, {amp1 / expected:.3g} times the crank's r w^2 "
            f"({expected:.3g} m/s^2)",
            "check the crank radius (in metres), that the motor turned the crank during the step, and that the "
            "sensor's axis of motion lies along the slider")


def analyse_step(
    t: np.ndarray,
    acc: np.ndarray,
    *,
    index: int,
    label: str,
    crank_radius: float,
    rod_length: float,
    clearance: float,
    commanded_hz: float | None = None,
    harmonics: int = DEFAULT_HARMONICS,
) -> StepResult:
    """Analyse one step's calibrated samples (t in s, acc (n, 3) in m/s^2)."""
    where = step_name(index, label)
    if acc.shape[0] < MIN_STEP_SAMPLES:
        raise DataError(f"{where}: only {acc.shape[0]} samples", f"record at least {MIN_STEP_SAMPLES} per step")
    if not (np.all(np.isfinite(acc)) and np.all(np.isfinite(t))):
        raise DataError(f"{where}: the samples contain NaN or infinite values", "repair or re-record the step")
    axis, along, angle_sd = principal_axis(acc)
    y = along - along.mean()
    try:
        start = interpolated_dft_frequency(t, y)
        span = t[-1] - t[0] + (t[-1] - t[0]) / (t.size - 1)
        if start * span < MIN_CYCLES:
            raise DataError(
                f"the record holds only {start * span:.2f} cycles at {start:.3g} Hz",
                f"record at least {MIN_CYCLES} crank turns (better 2.5 or more) per step",
            )
        rate = (t.size - 1) / (t[-1] - t[0])
        h = int(max(1, min(harmonics, np.floor(0.45 * rate / start))))
        fit = fit_sine(t, y, frequency=start, harmonics=h)
    except DataError as exc:
        raise DataError(f"{where}: {exc.message}", exc.hint) from None
    if not fit.converged:
        check_crank_motion(where, fit, t, crank_radius)  # a "fit" of noise alone often wanders: name the real cause
        raise CalibrationError(
            f"{where}: the sine fit did not converge (start {start:.4g} Hz, ended at {fit.frequency:.4g} Hz)",
            "check that the stand ran steadily and the record holds the motion",
        )
    noise_sd = robust_noise_sd(fit.residuals)
    backlash, knock_peak, knock_p, take_up = detect_backlash(t, fit.residuals, fit.frequency, float(fit.phase[0]),
                                                              noise_sd)
    if backlash:
        fit = _noise_only_covariance(t, fit, take_up)
    check_crank_motion(where, fit, t, crank_radius)

    # The radius and the mean speed from the crank-angle model (motion_fit): identical to the sine
    # fit when the motor runs steadily, and still right (with a wider u) when its speed wanders.
    if backlash:
        # The take-up's signature reaches far above the fitted harmonics; over a record that is not a whole
        # number of cycles it leaks into the speed (50 um of play: the mean speed off by 2-3 u at 8-10 Hz).
        # It is phase-locked: the folded residual of the sine fit, removed before the crank-motion fit.
        signature, _ = _phase_locked_template(t, fit.residuals, fit.frequency, float(fit.phase[0]))
        motion = fit_crank_motion(t, y - signature, fit.frequency, fit.harmonics)
    else:
        motion = fit_crank_motion(t, y, fit.frequency, fit.harmonics)
    checks = motion_checks(where, t, y, motion, fit if backlash else None, take_up)
    state = StepFit(index=index, label=label, n_samples=int(t.size), rate=float((t.size - 1) / (t[-1] - t[0])),
                    commanded_hz=commanded_hz, fit=fit, motion=motion, start=float(start),
                    fft_peak_hz=fft_peak_frequency(t, y), axis=axis, angle_sd=angle_sd, noise_sd=noise_sd,
                    backlash=backlash, knock_peak=knock_peak, knock_p=knock_p, take_up=take_up,
                    crank_radius=crank_radius,
                    rod_length=rod_length, clearance=clearance, times=t)
    return step_result(state, checks)


@dataclass
class StepFit:
    """What a step's fits left, from which its result is stated (again, when pool_noise revises its noise)."""

    index: int
    label: str
    n_samples: int
    rate: float
    commanded_hz: float | None
    fit: SineFit
    motion: CrankMotionFit
    start: float
    fft_peak_hz: float
    axis: np.ndarray
    angle_sd: float
    noise_sd: float
    backlash: bool
    knock_peak: float
    knock_p: float
    take_up: float                 # where the play is taken up, rad of crank angle after each dead centre
    crank_radius: float
    rod_length: float
    clearance: float
    times: np.ndarray | None = field(default=None, repr=False)   # the step's sample times, s (for _mirrored)


def play_from_third(a3: float, omega2: float) -> float:
    """Play b (m) taken up at the dead centres from the acceleration's third harmonic A_3 (m/s^2) at omega^2: the
    take-ups make the displacement a square wave of +-b/2 about the crank's, whose third harmonic is 2b / (3 pi)
    (the crank's kinematics have none), so b = 1.5 pi A_3 / (9 omega^2).  Linear: it maps A_3's u alike."""
    return 1.5 * np.pi * a3 / (9 * omega2)


def step_result(state: StepFit, checks: ResidualChecks) -> StepResult:
    """The step's estimates and their u, from its fits and the covariance the residual checks gave."""
    fit, motion, backlash = state.fit, state.motion, state.backlash
    crank_radius, rod_length, clearance = state.crank_radius, state.rod_length, state.clearance
    commanded_hz, axis, h = state.commanded_hz, state.axis, fit.harmonics
    f, grad_f = motion.mean_frequency_gradient()
    radius, grad_r = motion.radius_gradient()
    cov = checks.covariance
    u_f = float(np.sqrt(grad_f @ cov @ grad_f))
    u_radius = float(np.sqrt(grad_r @ cov @ grad_r))
    cov_rf = float(grad_r @ cov @ grad_f)
    omega2 = (2 * np.pi * f) ** 2
    speed_hz = motion.speed(np.linspace(-1.0, 1.0, 201)) / (2 * np.pi)
    spread = float(np.ptp(speed_hz))
    swings = np.count_nonzero(np.diff(np.sign(speed_hz - speed_hz.mean())) != 0)
    ripple_hz = float(max(swings, 1) / (2 * 2 * motion.half_span))
    unsteady = bool(motion.order > 1 and spread > SPEED_SPREAD * f)
    if motion.order == 1:
        amp1, u_amp1 = float(fit.amplitude[0]), float(fit.amplitude_uncertainty[0]) * checks.inflation
    else:
        # the first harmonic of the acceleration at the mean speed: A_1 = r omega^2
        amp1 = radius * omega2
        jac = np.array([omega2, 2 * radius * omega2 / f])
        u_amp1 = float(np.sqrt(jac @ np.array([[u_radius**2, cov_rf], [cov_rf, u_f**2]]) @ jac))
    play = u_play = 0.0
    if backlash and fit.harmonics >= 3:
        # The crank's kinematics have no odd harmonic above the first, so the
        # third is the play's.  For play of size b taken up at the dead centres
        # (a square wave of +-b/2) the third harmonic of the displacement is
        # 2b/(3 pi) and the first 2b/pi; the first adds to the slider's motion
        # with a phase set by how late the play is taken up.  Only its in-phase
        # part moves the radius, (2b/pi) sin(delta) for a take-up delta after
        # the dead centre; delta read from where the phase-locked residual's
        # energy arrives undercovered (50 % at 8-10 Hz with 20 um of play: the
        # pick-up's shape matters, not only its place), so the bound stays the
        # whole first harmonic.  Type B: rectangular within +-2b/pi.  A take-up found well after the dead
        # centres (the slider's inertia outweighs the rail's friction, detect_backlash) puts the share
        # (2b/pi) |sin delta| in phase with the crank, at one edge of the bound or the other, whichever
        # side the slider rides: a two-point distribution, sd that share, when it exceeds the rectangle's.
        third = float(fit.amplitude[2]) / (9 * omega2)
        play = play_from_third(float(fit.amplitude[2]), omega2)
        u_play = max(3 * third / np.sqrt(3), 3 * third * abs(np.sin(state.take_up)))
        u_radius = float(np.hypot(u_radius, u_play))
    model = crank_radius * omega2
    # measured / model first harmonic = A_1 / (r_caliper omega^2) = radius / r_caliper
    ratio = radius / crank_radius
    u_ratio = u_radius / crank_radius
    # the dof of u^2: the pooled bands' for this quantity, else the covariance's own; the play's term is exact
    dofs = checks.pooled_dof or {"radius": checks.dof, "frequency": checks.dof}
    radius_dof = dof_with_play(u_radius, u_play, dofs["radius"])
    frequency_dof = float(dofs["frequency"])
    # consistent with the caliper radius +- clearance (one step; verify_steps judges again over all steps)
    k_one = clearance_k(1, radius_dof)
    within = not outside_clearance(Estimate(radius, u_radius, "m"), crank_radius, clearance, k_one)

    # peak of the slider's motion (first h harmonics, knocks excluded) with its
    # uncertainty (GUM propagation through the max)
    idx = [fit.parameter_names.index(f"{kind}_{k}") for k in range(1, h + 1) for kind in ("amplitude", "phase")]
    amps_phases = np.array([val for k in range(h) for val in (fit.amplitude[k], fit.phase[k])])
    peak, peak_cov = propagate_covariance(lambda p: _peak_of_waveform(p, h), amps_phases,
                                          fit.covariance[np.ix_(idx, idx)] * checks.inflation**2)
    lam = crank_radius / rod_length
    commanded_model = None if commanded_hz is None else crank_radius * (2 * np.pi * commanded_hz) ** 2
    angles = np.degrees(np.arccos(np.clip(np.abs(axis), 0, 1)))
    return StepResult(
        index=state.index,
        label=state.label,
        n_samples=state.n_samples,
        commanded_hz=commanded_hz,
        frequency_hz=Estimate(f, u_f, "Hz"),
        fft_peak_hz=state.fft_peak_hz,
        start_frequency_hz=state.start,
        amplitude=Estimate(amp1, u_amp1, "m/s^2"),
        harmonic_amplitudes=Estimate(fit.amplitude.tolist(), (fit.amplitude_uncertainty * checks.inflation).tolist(),
                                     "m/s^2"),
        peak=Estimate(float(peak[0]), float(np.sqrt(peak_cov[0, 0])), "m/s^2"),
        model_amplitude=float(model),
        model_amplitude_bounds=(float((crank_radius - clearance) * omega2), float((crank_radius + clearance) * omega2)),
        model_peak=float(model * (1 + lam)),
        model_amplitude_commanded=commanded_model,
        ratio=Estimate(float(ratio), u_ratio, "1"),
        radius_m=Estimate(float(radius), u_radius, "m"),
        within_clearance=within,
        clearance_k=k_one,
        radius_dof=radius_dof,
        radius_k=coverage_factor(radius_dof),
        frequency_dof=frequency_dof,
        frequency_k=coverage_factor(frequency_dof),
        backlash=backlash,
        play_m=float(play),
        radius_play_uncertainty_m=float(u_play),
        knock_peak=state.knock_peak,
        knock_significance=state.knock_p,
        take_up_deg=float(np.degrees(state.take_up)),
        speed_unsteady=unsteady,
        speed_spread_hz=spread,
        speed_ripple_hz=ripple_hz,
        motor_limited=False,  # judged over all steps (mark_rolloff): shortfall, or hunting at the top
        axis=axis.tolist(),
        axis_angles_deg=angles.tolist(),
        axis_angle_uncertainty_deg=float(np.degrees(state.angle_sd)),
        residual_sd=fit.residual_sd,
        noise_sd=state.noise_sd,
        n_iterations=fit.n_iterations,
        fit=fit,
        harmonics=fit.harmonics,
        speed_order=motion.order,
        residual_checks=checks.to_dict(),
        notes=checks.notes,
        state=state,
        checks=checks,
    )


def pool_noise(steps: list[StepResult]) -> None:
    """Each short step's u from the noise spectrum all steps of the sensor show, not from its own residuals alone.

    A 1-s step cannot show the noise where its own motion lives: its fit takes the noise out there, and
    under 1/f noise the spectrum rises within a few bins, so the step's own AR model misses it (u at
    2.5 Hz half the true one).  The steps share one sensor, axis and record: the other steps' residuals
    show the noise at this step's crank frequency.  residuals.pooled_noise_model finds the spectrum in
    bands from every step's residuals (each step's projection accounted for), and a level per step
    (a step that shook more keeps its own level).  Every step whose residuals were found correlated gets
    the sandwich with that spectrum at its level: batch means over blocks of a few correlation times
    (milliseconds under 1/f noise) see the slow noise no better than the step's own AR model.  A step
    whose residual power stands out from the pool (a motion the model misses; correlated residuals get
    no other lack-of-fit test) keeps its own level, is warned, and is left out of the pool while two
    others remain.  Steps with backlash (their phase-locked template removed) and steps at another
    sampling rate are not pooled.  Replaces the revised steps in ``steps``.
    """
    eligible = [i for i, s in enumerate(steps) if s.state is not None and s.checks is not None and not s.backlash]
    groups: list[list[int]] = []
    for i in eligible:   # one sampling rate per group (within 0.5 %): the spectrum is per sample
        rate = steps[i].state.rate
        group = next((g for g in groups if abs(steps[g[0]].state.rate / rate - 1.0) < 0.005), None)
        if group is None:
            groups.append([i])
        else:
            group.append(i)
    for members in groups:
        if len(members) < 2:
            continue
        model = pooled_noise_model([(steps[i].state.motion.jacobian, steps[i].state.motion.residuals)
                                    for i in members], warn_ratio=LOF_WARN)
        # one smooth AR model explains every step's residuals (white, AR-like noise): each step's own u
        # stands, resting on a model fitted to all its samples.  Otherwise (1/f: the rise at a slow step's
        # own frequency is what its residuals cannot show) every step takes the pooled bands, a step
        # whose residuals passed as white too: its own whiteness test could not see that noise either
        # the steps' own u judged against the bands at their own speeds: the AR test sums every band, and the
        # one or two low bands where 1/f noise outgrows a smooth model drown among thirty that agree (about 1
        # run in 8 passed it, keeping a slow step's u at half its value); this tests the u that would stand.
        # A step whose own u falls short says the sensor's noise is not what the steps' own models assume:
        # like a failed AR test, every step then takes the bands
        judged = [_judge_own_u(steps[i], model, k, len(members)) for k, i in enumerate(members)]
        short = [k for k, j in enumerate(judged) if j["short"]]
        coloured = model.ar_p_value < POOL_AR_ALPHA or bool(short)
        if model.ar_p_value < POOL_AR_ALPHA:
            why = f"one AR model of all of them fails, p = {model.ar_p_value:.1g}"
        elif short:
            worst = min(short, key=lambda k: judged[k]["p_value"])
            why = (f"{steps[members[worst]].where}'s own u would be {judged[worst]['ratio']:.2f}x the one they give "
                   f"at its speed, p = {judged[worst]['p_value']:.1g}")
        for k, i in enumerate(members):
            step, checks = steps[i], steps[i].checks
            flagged = bool(model.stands_out[k]) and checks.correlated   # a white step has its own lack-of-fit test
            if not (coloured or flagged or checks.correlated):
                continue
            motion = step.state.motion
            noise = model.for_fit(k)
            level, p_value = float(model.levels[k]), float(model.p_values[k])
            used = coloured or flagged
            pooled_dof, shares = judged[k]["dof"], judged[k]["shares"]
            own_kept = used and judged[k]["long"]
            if own_kept:
                # the bands fell short where this step's u lives (a band whose moments the steeper band below it
                # explained away, solved at level 0: under red 1/f^1.5 noise the 3 Hz step's radius, 72 % in the
                # 1.6-3.2 Hz band, came out with half its u and 51 dof): its own residuals' u stands
                cov, method = checks.covariance, checks.method
                used, pooled_dof = False, None
            elif used:
                normal = motion.jacobian.T @ motion.jacobian
                cov = ar_sandwich_covariance(normal, motion.jacobian, motion.residuals, noise=noise).covariance
                method = f"{noise.label} spectral sandwich over {int(model.pooled.sum())} steps"
            else:
                cov, method = checks.covariance, checks.method
            if checks.correlated:   # its one note said where its u came from: now from here
                notes = [f"{step.where}: {checks.tested.describe()}; u from the {method}"]
                if coloured and model.ar_p_value >= POOL_AR_ALPHA:
                    notes[0] += f" (the steps together show more noise than the steps' own models: {why})"
            elif own_kept:          # a white step's lack-of-fit warning stands; the note below says why its u stays
                notes = list(checks.notes)
            else:                   # a white step's lack-of-fit warning stands
                notes = list(checks.notes) + [
                    f"{step.where}: its residuals pass as white, but the steps together show coloured noise "
                    f"({why}): u from the {method}"]
            if own_kept:
                notes.append(f"{step.where}: the noise the steps together show falls short of its own at its speed "
                             f"(its own u {judged[k]['long_ratio']:.2f}x theirs, p = {judged[k]['long_p_value']:.1g}): "
                             "its own u is kept")
            if flagged:
                notes.append(f"{step.where}: its residuals hold {np.sqrt(level):.2f}x the noise the other steps show "
                             f"(F test p = {p_value:.1g}): the motion differs from the model here, or this step "
                             "shook more; its u is from its own level"
                             + ("" if model.pooled[k] else ", and it is left out of the pooled noise"))
            if not used:
                pooled_dof = None
            pooled = {"steps": int(model.pooled.sum()), "level": level, "p_value": p_value,
                      "ar_p_value": float(model.ar_p_value), "used": bool(used),
                      "own_u_ratio": judged[k]["ratio"], "own_u_p_value": judged[k]["p_value"],
                      "own_u_kept": bool(own_kept),
                      "dof": float(model.dof[k]), "in_pool": bool(model.pooled[k]),
                      **({} if pooled_dof is None else {"radius_dof": pooled_dof["radius"],
                                                        "frequency_dof": pooled_dof["frequency"]}),
                      "unseen_bands_hz": [[float(noise.edges[b] * step.state.rate),
                                           float(noise.edges[b + 1] * step.state.rate)]
                                          for b in np.flatnonzero(~noise.seen)]}
            revised = replace(checks, covariance=cov, inflation=_inflation(motion, cov, checks.white), method=method,
                              notes=notes, pooled=pooled, pooled_dof=pooled_dof,
                              pooled_model=model if pooled_dof is not None else None, pooled_index=k,
                              radius_shares=None if pooled_dof is None else shares[0])
            steps[i] = step_result(step.state, revised)


def _judge_own_u(step: StepResult, model: PooledNoise, k: int, n_steps: int) -> dict:
    """A step's u from the pooled bands against its own (of the radius and of the speed): the bands' effective
    dof for both, and whether its own u is significantly below theirs.

    The bands' variance of a quantity is level_k * shares @ levels (``band_variance_shares``), with
    effective dof nu (Welch-Satterthwaite over the band powers behind it, ``PooledNoise.variance_dof``).
    Were the step's own variance v_own right, the bands' v_b would be v_own chi-square(nu) / nu: one-sided
    p = P(chi2_nu > nu v_b / v_own), Bonferroni over the two quantities and the steps, at OWN_U_ALPHA.
    Returns dof ({"radius", "frequency"}), shares (2, m), short, ratio (the smaller u_own / u_bands) and
    its p_value.
    """
    motion, checks = step.state.motion, step.checks
    gradients = np.array([motion.radius_gradient()[1], motion.mean_frequency_gradient()[1]])
    rows = gradients @ np.linalg.pinv(motion.jacobian.T @ motion.jacobian)
    shares = band_variance_shares(motion.jacobian, rows, model.noise.edges)
    dof = {"radius": model.variance_dof(k, shares[0]), "frequency": model.variance_dof(k, shares[1])}
    ratio, p_value, long_ratio, long_p = 1.0, 1.0, 1.0, 1.0
    for q, name in enumerate(("radius", "frequency")):
        own = float(gradients[q] @ checks.covariance @ gradients[q])
        bands = float(model.levels[k] * (shares[q] @ model.noise.levels))
        if own <= 0 or bands <= 0:
            continue
        nu = dof[name]
        p = float(stats.chi2.sf(nu * bands / own, nu)) if np.isfinite(nu) else float(bands <= own)
        if p < p_value:
            ratio, p_value = float(np.sqrt(own / bands)), p
        # and the other way: the bands' u significantly below what the step's own residuals show at its speed
        p = float(stats.chi2.cdf(nu * bands / own, nu)) if np.isfinite(nu) else float(bands >= own)
        if p < long_p:
            long_ratio, long_p = float(np.sqrt(own / bands)), p
    return {"dof": dof, "shares": shares, "short": p_value * 2 * n_steps < OWN_U_ALPHA, "ratio": ratio,
            "p_value": p_value, "long": long_p * 2 * n_steps < OWN_U_ALPHA, "long_ratio": long_ratio,
            "long_p_value": long_p}


def check_neighbours(steps: list[StepResult]) -> None:
    """A step whose frequency is far off the line through its neighbours is the wrong data: say which."""
    if len(steps) < 3:
        return
    f = np.array([s.frequency_hz.value for s in steps])
    for i, step in enumerate(steps):
        # the typical spacing of the *other* steps, so the suspect cannot widen its own tolerance
        others = np.delete(f, i)
        spacing = max(float(np.median(np.abs(np.diff(others)))), 0.05 * float(np.median(others)))
        if i == 0:
            expected, neighbours = f[1], [f[1]]
        elif i == len(steps) - 1:
            expected, neighbours = f[-2], [f[-2]]
        else:
            expected, neighbours = 0.5 * (f[i - 1] + f[i + 1]), [f[i - 1], f[i + 1]]
        # an end step may legitimately sit one spacing away from its only neighbour
        limit = NEIGHBOUR_FACTOR * spacing + (spacing if i in (0, len(steps) - 1) else 0.0)
        if abs(f[i] - expected) > limit:
            raise DataError(
                f"{step.where}: dominant frequency {f[i]:.3f} Hz disagrees with its neighbours "
                f"({', '.join(f'{v:.3f}' for v in neighbours)} Hz) far more than the steps differ ({spacing:.3f} Hz)",
                "wrong file, or the stand was not running the intended speed: drop or re-record that step",
            )


def _displacement_harmonics(step: StepResult) -> tuple[np.ndarray, np.ndarray]:
    """The displacement's 1st and 2nd harmonics (hypot(a_k, b_k), m) of the crank-motion fit and their covariance
    (the step's, with the play's share of u(radius) on the first)."""
    motion = step.state.motion
    grads, values = [], []
    for k in (1, 2):
        a, b = motion.linear[2 * k - 1], motion.linear[2 * k]
        d = float(np.hypot(a, b))
        g = np.zeros(motion.n_parameters)
        g[motion.order + 2 * k - 1], g[motion.order + 2 * k] = a / d, b / d
        grads.append(g)
        values.append(d)
    g = np.array(grads)
    cov = g @ step.checks.covariance @ g.T
    # the Type B terms u(radius) carries (play, an unfollowed ripple's sidebands) on the first; the ripple's on the
    # second: without the ripple's term on the first, a 4.5 Hz step under a 5 Hz wobble scattered 3x its u
    cov[0, 0] += step.radius_play_uncertainty_m**2 + step.ripple_radius_uncertainty_m**2
    cov[1, 1] += (step.ripple_second_harmonic_share * values[1]) ** 2
    return np.array(values), cov


def _mirrored(step: StepResult) -> bool:
    """Whether a step's phase-locked event is the same, mirrored, at both dead centres: then it holds odd harmonics
    only (nearly) and leaves the even ones, which check_compliance reads, alone.  The crank-angle fold of the sine
    fit's residuals is split into its part that repeats half a turn on (even harmonics) and its part that flips
    (odd): mirrored when the first's power above the noise is below MIRROR_SHARE of the second's.  Friction
    reversing at the two dead centres (a force step of the same size either way, ringing a compliant link) is
    mirrored to within a few per cent; play taken up well after the dead centres (the held-out dead zone) is not
    (the two powers alike)."""
    fit = step.state.fit
    if step.state.times is None or step.state.noise_sd <= 0:
        return False
    t, resid = step.state.times, fit.residuals
    theta = np.mod(2 * np.pi * fit.frequency * t + float(fit.phase[0]), 2 * np.pi)
    half = int(np.clip(resid.size / max(fit.frequency * (t[-1] - t[0]), 1e-12) // 4, 4, 2048))   # 2 samples a bin
    idx = np.minimum((theta / (2 * np.pi) * 2 * half).astype(int), 2 * half - 1)
    counts = np.bincount(idx, minlength=2 * half)
    means = np.bincount(idx, weights=resid, minlength=2 * half) / np.maximum(counts, 1)
    variance = step.state.noise_sd**2 * (1 / np.maximum(counts[:half], 1) + 1 / np.maximum(counts[half:], 1))
    repeats = float(np.mean((means[:half] + means[half:]) ** 2 / variance)) - 1.0
    flips = float(np.mean((means[:half] - means[half:]) ** 2 / variance)) - 1.0
    return bool(flips > 0 and repeats < MIRROR_SHARE * flips)


def ring_frequency(step: StepResult) -> tuple[float, float, float]:
    """The frequency a step's phase-locked event rings at (Hz), the power of that ring (for weighting) and the
    bin it is read on (Hz: the zero-padded periodogram's spacing, the floor of its u).

    The sine fit's residuals folded by crank angle, one sample per bin (the fold's Nyquist is the sampling's), in
    the window after each take-up (``dead_centre_window``): its mean removed, each window's periodogram (zero-padded
    to 0.5 Hz) summed over the two, and its peak above 2.5 cycles in the window (slower is the take-up's own shape,
    a step or a free flight, not a ring) up to 0.45 of the sampling rate.  A spring rings at its own resonance: a
    flexing link at the one its harmonics' trend shows (check_compliance), a contact with play at the contact's."""
    state = step.state
    fit = state.fit
    t, resid = state.times, fit.residuals
    centres, means, counts = fold_residuals(t, resid, fit.frequency, float(fit.phase[0]), samples_per_bin=1.0)
    n_bins = centres.size
    dt = 1.0 / (fit.frequency * n_bins)
    take_up = np.radians(step.take_up_deg)
    after = min(0.25, 0.030 * fit.frequency) * 2 * np.pi
    before = 0.02 * 2 * np.pi
    length = int((after + before) / (2 * np.pi) * n_bins)
    if length < 8:
        return float("nan"), 0.0, float("nan")
    n_fft = int(2 ** np.ceil(np.log2(max(2 * state.rate, 2 * length))))
    freqs = np.fft.rfftfreq(n_fft, dt)
    power = np.zeros(freqs.size)
    for start in (take_up, take_up + np.pi):
        first = int(np.floor((start - before) / (2 * np.pi) * n_bins))
        idx = np.mod(first + np.arange(length), n_bins)
        window = means[idx] - means[idx].mean()
        power += np.abs(np.fft.rfft(window * np.hanning(length), n_fft)) ** 2
    band = (freqs >= 2.5 / (length * dt)) & (freqs <= 0.45 * state.rate)
    if not band.any():
        return float("nan"), 0.0, float("nan")
    k = int(np.argmax(np.where(band, power, -np.inf)))
    return float(freqs[k]), float(power[k]), float(freqs[1] - freqs[0])


def _fit_compliance(steps: list[StepResult], judged: list[int]) -> tuple[float, float, float] | None:
    """The steps' 1st and 2nd displacement harmonics fitted with r / (1 - c omega^2) and d / (1 - 4 c omega^2)
    against c = 0: (c, u(c), the likelihood ratio's p-value), significant or not; None with fewer than 3 steps."""
    if len(judged) < MIN_COMPLIANCE_STEPS:
        return None
    omega2 = np.array([(2 * np.pi * steps[i].frequency_hz.value) ** 2 for i in judged])
    values, whiten = [], []
    for i in judged:
        v, cov = _displacement_harmonics(steps[i])
        values.append(v)
        whiten.append(np.linalg.inv(np.linalg.cholesky(cov)))
    values = np.array(values)

    def residuals(p, free=True):
        r, d, c = p if free else (*p, 0.0)
        model = np.column_stack([r / (1 - c * omega2), d / (1 - 4 * c * omega2)])
        return np.concatenate([w @ (v - m) for w, v, m in zip(whiten, values, model, strict=True)])

    start = values.mean(axis=0)
    null = optimize.least_squares(lambda p: residuals(p, free=False), start, x_scale=start)
    scale = np.array([*start, 0.1 / omega2.max()])
    alt = optimize.least_squares(residuals, [*null.x, 0.0], x_scale=scale,
                                 bounds=([0, 0, -1 / omega2.max()], [np.inf, np.inf, 0.9 / (4 * omega2.max())]))
    chi_null, chi_alt = 2 * null.cost, 2 * alt.cost
    p_value = float(stats.chi2.sf(max(chi_null - chi_alt, 0.0), 1))
    dof = 2 * len(judged) - 3
    birge = max(chi_alt / dof, 1.0) if dof > 0 else 1.0
    cov = np.linalg.pinv(alt.jac.T @ alt.jac) * birge
    return float(alt.x[2]), float(np.sqrt(cov[2, 2])), p_value


def check_compliance(steps: list[StepResult]) -> dict | None:
    """A link or a slider mounting that flexes: the harmonics grow with speed beyond the rigid crank's law.

    A rigid crank's displacement harmonics are fixed by its geometry (r cos phi exactly, and the 2nd about
    r lambda / 4) at every speed; play adds odd harmonics only.  A spring between the crank and the sensor
    (the rod, the pin, the slider's mounting) with its resonance well above the crank turns amplifies harmonic n
    by 1 / (1 - n^2 c omega^2), c = 1 / omega_r^2: the radius from the motion rises as (f / f_r)^2 and the 2nd
    harmonic four times as fast.  Fitted over the steps (r, d_2 and c, each step's two harmonics with their
    covariance) against c = 0: when the likelihood ratio is significant at COMPLIANCE_ALPHA the resonance is
    named and each step's radius is corrected to zero speed, r (1 - c omega^2), its u carrying the correction's
    (common to all steps).  A sensor whose response rises with frequency looks the same: the warning says so.
    A trend the other way (harmonics falling with speed: a response that rolls off) is not corrected: u(radius)
    takes the bias it implies.  Beyond COMPLIANCE_REFUSE the crank law with one resonance is not trusted: refused.
    Returns what was found (for the JSON and the warning), None when nothing was.
    """
    # a step whose dead-centre event differs between the two dead centres carries even harmonics of its own; a step
    # whose speed wandered had its harmonics fitted jointly with a speed profile, whose terms near the crank's rate
    # trade against the 2nd harmonic: a 5 Hz wobble followed to order 22 at 6.5 Hz left d_2 up to 8 u(d_2) off (the
    # covariance knows the profile's noise, not what it misses), which read as a flexing link in 2 of 25 runs
    judged = compliance_steps(steps)
    fitted = _fit_compliance(steps, judged)
    if fitted is not None and fitted[2] < COMPLIANCE_ALPHA and fitted[0] > 0:
        # steps whose dead-centre event is real play (a knock at another frequency than the link's resonance,
        # _is_link_ringing) carry that play's own low harmonics: judged again without them
        played = [i for i in judged if steps[i].backlash and not _is_link_ringing(steps, fitted[0], fitted[1])]
        if played:
            judged = [i for i in judged if i not in played]
            fitted = _fit_compliance(steps, judged)
    # named whatever the trend's significance: a stiff link's ring at 450 Hz moves the harmonics too little to be
    # seen, yet its frequency is what the trend admits, and it is not play
    ring = _name_link_ringing(steps, fitted[0], fitted[1]) if fitted is not None else None
    if fitted is None or (fitted[2] >= COMPLIANCE_ALPHA and ring is None):
        return None
    c, u_c, p_value = fitted
    found = {"trend_c_s2": c, "trend_c_uncertainty_s2": u_c}
    if ring is not None:
        # the link the ring names amplifies the harmonics whether or not the trend could show it (a 450 Hz link
        # moves a 10 Hz step's radius by 0.05 %, several times its u): its resonance corrects every radius
        c, u_c = compliance_with_ring(c, u_c, *ring)
        found.update(ring_hz=ring[0], ring_uncertainty_hz=ring[1])
    omega2 = np.array([(2 * np.pi * steps[i].frequency_hz.value) ** 2 for i in judged])
    top = float(omega2.max())
    found.update({"c_s2": c, "c_uncertainty_s2": u_c, "p_value": p_value, "steps": len(judged),
                  "second_harmonic_gain_at_top": float(1 / (1 - 4 * c * top))})
    if c > 0:
        f_r = 1 / (2 * np.pi * np.sqrt(c))
        u_fr = 0.5 * f_r * u_c / c
        found.update(resonance_hz=f_r, resonance_uncertainty_hz=u_fr)
        trend = (f"the slider's harmonics grow with speed beyond the rigid crank's law (its 2nd harmonic "
                 f"{100 * (found['second_harmonic_gain_at_top'] - 1):.2g} % above the 1st's share at "
                 f"{np.sqrt(top) / (2 * np.pi):.3g} Hz, p = {p_value:.1g})")
        if fitted[2] >= COMPLIANCE_ALPHA:
            trend = (f"the link rings at {ring[0]:.0f} +- {ring[1]:.2g} Hz where the rail's friction reverses, its "
                     f"resonance, which raises the radius from the motion by {100 * c * top:.2g} % at "
                     f"{np.sqrt(top) / (2 * np.pi):.3g} Hz: more than the harmonics' trend alone could show (p = "
                     f"{p_value:.1g})")
        what = (f"{trend}: the link or the slider's mounting flexes, as a resonance near {f_r:.0f} +- {u_fr:.2g} Hz "
                "would" + ("" if ring is not None else " (or the sensor's response rises with frequency)"))
        if 4 * c * top > COMPLIANCE_REFUSE:
            raise CalibrationError(
                f"{what}; that close to the fastest step the slider's motion is not a crank's with one resonance "
                "added, and the radius cannot be corrected", "stiffen the link and the sensor's mounting, or "
                "verify with slower steps only")
        found["warning"] = (f"{what}; each step's radius is corrected to zero speed, r (1 - (f / f_r)^2), "
                            "with the correction's uncertainty in u(radius)")
    else:
        found["warning"] = (f"the slider's harmonics shrink with speed against the rigid crank's law (its 2nd "
                            f"harmonic {100 * (1 - found['second_harmonic_gain_at_top']):.2g} % below the 1st's share "
                            f"at {np.sqrt(top) / (2 * np.pi):.3g} Hz, p = {p_value:.1g}): the sensor's response falls "
                            "with frequency, or the stand damps its motion; u(radius) includes the bias that implies")
    # every step: the spring amplifies the steps the trend left out (uneven play, a wandering speed) alike
    for i, step in enumerate(steps):
        w2 = (2 * np.pi * step.frequency_hz.value) ** 2
        radius, u_radius = step.radius_m.value, step.radius_m.uncertainty
        u_stat = float(np.sqrt(max(u_radius**2 - step.radius_play_uncertainty_m**2, 0.0)))
        if c > 0:
            factor = 1 - c * w2
            u_corr = radius * w2 * u_c
            value = radius * factor
        else:
            factor = 1.0
            u_corr = radius * w2 * np.hypot(c, u_c)
            value = radius
        u_new = float(np.sqrt((u_stat * factor) ** 2 + step.radius_play_uncertainty_m**2 + u_corr**2))
        u_common = float(np.hypot(step.radius_play_uncertainty_m, u_corr))
        radius_dof = dof_with_play(u_new, u_common, step.radius_dof if np.isfinite(step.radius_dof) else np.inf)
        steps[i] = replace(step, radius_m=Estimate(float(value), u_new, "m"),
                           ratio=Estimate(float(value / step.state.crank_radius), u_new / step.state.crank_radius, "1"),
                           compliance_factor=float(factor), radius_compliance_uncertainty_m=float(u_corr),
                           radius_dof=radius_dof, radius_k=coverage_factor(radius_dof))
    return found


def compliance_steps(steps: list[StepResult]) -> list[int]:
    """The steps check_compliance judges: two harmonics fitted, a steady crank, no uneven event at the dead centres
    (a step whose event differs between the two dead centres carries even harmonics of its own; a step whose speed
    wandered had its harmonics fitted jointly with a speed profile, whose terms near the crank's rate trade against
    the 2nd harmonic: a 5 Hz wobble followed to order 22 at 6.5 Hz left d_2 up to 8 u(d_2) off, the covariance
    knowing the profile's noise, not what it misses, which read as a flexing link in 2 of 25 runs)."""
    return [i for i, s in enumerate(steps) if s.state is not None and s.checks is not None
            and s.state.motion.harmonics >= 2 and not s.speed_unsteady and (not s.backlash or _mirrored(s))]


def compliance_status(steps: list[StepResult], found: dict | None) -> dict:
    """Whether the flexing-link check was made, over how many steps, and why not (for quality and the check lines).

    The trend with speed has three unknowns (r, d_2, c): it needs MIN_COMPLIANCE_STEPS steady steps."""
    judged = compliance_steps(steps)
    status = {"made": len(judged) >= MIN_COMPLIANCE_STEPS, "steps": len(judged), "needs": MIN_COMPLIANCE_STEPS,
              "found": found is not None}
    if found is not None:
        status["resonance_hz"] = found.get("resonance_hz")
        status["p_value"] = found["p_value"]
        status["ring_hz"] = found.get("ring_hz")   # the link named by its ring: its resonance corrects the radii
    if not status["made"]:
        left = [(sum(1 for s in steps if s.speed_unsteady), "whose speed wandered"),
                (sum(1 for s in steps if s.state is not None and s.state.motion.harmonics < 2),
                 "with one harmonic fitted"),
                (sum(1 for s in steps if s.backlash and not s.speed_unsteady and not _mirrored(s)),
                 "with play taken up unevenly")]
        why = f"only {len(judged)} of {len(steps)} steps could be judged (it needs {MIN_COMPLIANCE_STEPS}"
        out = [f"{n} {what}" for n, what in left if n]
        status["why"] = why + ("; left out: " + ", ".join(out) if out else "") + ")"
    return status


def _is_link_ringing(steps: list[StepResult], c: float, u_c: float) -> bool:
    """Whether the steps' events at the dead centres are a flexing link ringing, not play, by their frequency.

    Where the rail's friction reverses, at the dead centres, a spring link takes a force step: it rings at its own
    resonance, the one whose compliance c = 1 / omega_r^2 the harmonics' trend with speed shows (check_compliance).
    Play is crossed where the force through the link reverses, and its knock rings at the contact's frequency,
    which the link's harmonics need not show.  So a dead-centre event is the link ringing when the compliance its
    ring frequency implies (ring_frequency, the median over the flagged steps: one cause for all) agrees with the
    trend's c within RING_AGREE times their combined u (the trend's, and the ring frequencies' scatter, never below
    the bin they are read on), that u below c_ring itself (a trend that could tell that compliance from none), and
    every flagged step rings within RING_SPREAD of the median (one resonance at every speed; a take-up's own shape
    has none).  Where the trend does not also rule out a rigid link (c within RING_AGREE u of 0: a rigid link's
    trend then agrees with a knock at one contact frequency too), the event must also keep its size with speed
    (knock_growth below RING_GROWTH): a friction step is the same force at every speed, an impact is not.  An event
    after the dead centres is play whatever it rings at: friction does not reverse there, so a link without play
    takes no force step there.  (A lost-motion size cannot decide it: play at a stiff contact and a ringing
    compliant link shift the slider alike within a factor of 2-4.)
    """
    flagged = _flagged_at_dead_centres(steps)
    if not flagged or not (np.isfinite(c) and np.isfinite(u_c)):
        return False
    ring = one_ring(flagged)
    if ring is None:
        return False
    f_ring, u_f, found = ring
    c_ring = 1.0 / (2 * np.pi * f_ring) ** 2
    u_both = float(np.hypot(u_c, 2 * c_ring * u_f / f_ring))
    # and only where the trend could tell that compliance from none (u below c_ring): steps too few or too close
    # in speed admit any ring, and then the event stays play, as without a trend
    if not (u_both < c_ring and abs(c - c_ring) <= RING_AGREE * u_both):
        return False
    if c > RING_AGREE * u_both:   # the trend rules out a rigid link: its ring is the link's
        return True
    # a trend that cannot rule out a rigid link agrees with a knock at one contact frequency as well: the link's
    # ring is a friction step's, the same size at every speed; a knock grows with speed (RING_GROWTH).  A friction
    # that turns over a broad band rings the link more as the speed rises, but at one timing against the dead
    # centres; a knock comes a fixed crank angle after them, later in time at a slower step (RING_TIMING_ALPHA).
    # A link that sticks until it breaks free comes late too, but loses less motion than play waiting there would
    return (knock_growth(flagged) < RING_GROWTH or ring_keeps_timing(found, f_ring, u_f)
            or lost_motion_below_hold(found, f_ring, u_f))


def _flagged_at_dead_centres(steps: list[StepResult]) -> list[StepResult]:
    """The steps flagged with play taken up at the dead centres (what _is_link_ringing judges)."""
    return [s for s in steps if s.backlash and s.take_up_deg == 0 and s.knock_peak > 0 and s.state is not None
            and s.state.times is not None]


def one_ring(flagged: list[StepResult]) -> tuple[float, float, list[StepResult]] | None:
    """The one frequency the flagged steps' events ring at (Hz: the median of ring_frequency), its u (Hz) and the
    steps read; None when no step shows a ring or one rings beyond RING_SPREAD of the median (no one resonance)."""
    found = [(ring_frequency(s), s) for s in flagged]
    found = [(ring, s) for ring, s in found if np.isfinite(ring[0])]
    if not found:
        return None
    rings = np.array([ring[0] for ring, _ in found])
    f_ring = float(np.median(rings))
    if np.max(np.abs(rings / f_ring - 1.0)) > RING_SPREAD:
        return None
    # the scatter of the steps' rings, but never below the bin they are read on: steps that all peak in one bin
    # have a scatter of 0, not a frequency known to 0
    bin_hz = max(ring[2] for ring, _ in found)
    u_f = max(float(np.std(rings, ddof=1) / np.sqrt(rings.size)), bin_hz) if rings.size > 1 else 0.05 * f_ring
    return f_ring, u_f, [s for _, s in found]


def lost_motion_below_hold(steps: list[StepResult], f_ring: float, u_f: float) -> bool:
    """Whether some step's dead-centre event loses less motion than play waiting at the dead centres must.

    Play is crossed at the dead centres only where the rail's friction F outweighs the slider's inertia there,
    F >= m A_1 (1 - lambda) at the weaker (outer) one; the contact that then takes it up (stiffness m (2 pi
    f_ring)^2: it rings at f_ring with the slider's mass) gives way by F / k each way, so the lost motion is at
    least 2 A_1 (1 - lambda) / (2 pi f_ring)^2, plus the gap.  The lost motion is read as step_result's play,
    from the third harmonic (play_from_third), with its u; the bound's u is the ring frequency's.  A step below the bound by more than the
    one-sided normal quantile at RING_TIMING_ALPHA over the steps (Sidak) is not play held there: a link that
    sticks until it is stretched enough to break free.  |A_3| only reads high under noise, so the test errs
    towards play.  Steps with fewer than three harmonics fitted cannot say."""
    judged = [s for s in steps if len(np.atleast_1d(s.harmonic_amplitudes.value)) >= 3]
    if not judged or not (np.isfinite(f_ring) and f_ring > 0):
        return False
    z = float(stats.norm.isf(1.0 - (1.0 - RING_TIMING_ALPHA) ** (1.0 / len(judged))))
    ring2 = (2 * np.pi * f_ring) ** 2
    for s in judged:
        omega2 = (2 * np.pi * s.frequency_hz.value) ** 2
        lam = s.state.crank_radius / s.state.rod_length
        a1 = float(np.atleast_1d(s.harmonic_amplitudes.value)[0])
        a3, u_a3 = (float(np.atleast_1d(v)[2]) for v in (s.harmonic_amplitudes.value, s.harmonic_amplitudes.uncertainty))
        lost, u_lost = play_from_third(a3, omega2), play_from_third(u_a3, omega2)
        hold = 2 * a1 * (1 - lam) / ring2
        u = float(np.hypot(u_lost, hold * 2 * u_f / f_ring))
        if u > 0 and hold - lost > z * u:
            return True
    return False


def ring_phase(step: StepResult, f_ring: float) -> tuple[float, float, float]:
    """The phase (rad) at ``f_ring`` of a step's phase-locked event timed from the dead centres, its u from the noise,
    and its rate of change with f_ring (rad/Hz, for the u the ring frequency's own u adds).

    The sine fit's residuals in the window (as ``dead_centre_window``) about each dead centre, each sample timed
    from its dead centre by its own crank angle (not a fold's bin: at 450 Hz a bin one sample wide spans 80 deg of
    the ring, and a step of a few turns fills it unevenly).  The event flips between the two dead centres (the
    friction, or the play's side, reverses): the sum at the second is subtracted from the one at the first."""
    fit = step.state.fit
    theta = 2 * np.pi * fit.frequency * step.state.times + float(fit.phase[0])
    after = min(0.25, 0.030 * fit.frequency) * 2 * np.pi
    before = 0.02 * 2 * np.pi
    z, dz, n = 0j, 0j, 0
    for sign, dead_centre in ((1.0, 0.0), (-1.0, np.pi)):
        delta = np.angle(np.exp(1j * (theta - dead_centre)))
        near = (delta >= -before) & (delta <= after)
        tau = delta[near] / (2 * np.pi * fit.frequency)
        turn = np.exp(-2j * np.pi * f_ring * tau)
        z += sign * np.sum(fit.residuals[near] * turn)
        dz += sign * np.sum(fit.residuals[near] * (-2j * np.pi * tau) * turn)
        n += int(near.sum())
    if abs(z) == 0:
        return float("nan"), float("inf"), 0.0
    return float(np.angle(z)), float(step.state.noise_sd * np.sqrt(n / 2) / abs(z)), float(np.imag(dz / z))


def ring_keeps_timing(steps: list[StepResult], f_ring: float, u_f: float) -> bool:
    """Whether the steps' events ring at one phase against the dead centres (ring_phase at f_ring): their phases'
    scatter about the weighted circular mean is within what the noise and the ring frequency's u (``u_f``) explain,
    by a chi-square at RING_TIMING_ALPHA.  Needs two steps."""
    if len(steps) < 2:
        return False
    phases, u = [], []
    for s in steps:
        phase, u_noise, slope = ring_phase(s, f_ring)
        phases.append(phase)
        u.append(float(np.hypot(u_noise, slope * u_f)))
    phases, u = np.array(phases), np.array(u)
    if not (np.all(np.isfinite(phases)) and np.all(np.isfinite(u)) and np.all(u > 0)):
        return False
    weight = 1.0 / u**2
    mean = np.angle(np.sum(weight * np.exp(1j * phases)))
    chi2 = float(np.sum(weight * np.angle(np.exp(1j * (phases - mean))) ** 2))
    return bool(stats.chi2.sf(chi2, phases.size - 1) >= RING_TIMING_ALPHA)


def knock_growth(steps: list[StepResult]) -> float:
    """The exponent of the dead-centre event's size against the crank's speed over the steps (knock_peak ~ f^g,
    least squares in logs); NaN with fewer than two speeds."""
    speeds = np.array([s.frequency_hz.value for s in steps])
    knocks = np.array([s.knock_peak for s in steps])
    keep = (speeds > 0) & (knocks > 0)
    if keep.sum() < 2 or np.ptp(np.log(speeds[keep])) == 0:
        return float("nan")
    return float(np.polyfit(np.log(speeds[keep]), np.log(knocks[keep]), 1)[0])


def _name_link_ringing(steps: list[StepResult], c: float, u_c: float) -> tuple[float, float] | None:
    """Steps flagged with play at the dead centres whose event is the flexing link ringing (_is_link_ringing):
    named so; returns the link's ring frequency and its u (Hz, one_ring), None when the events are not its ring."""
    if not _is_link_ringing(steps, c, u_c):
        return None
    f_ring, u_f, _ = one_ring(_flagged_at_dead_centres(steps))
    for i, s in enumerate(steps):
        if s.backlash and s.take_up_deg == 0:
            steps[i] = replace(s, backlash=False, link_ringing=True, ring_hz=float(ring_frequency(s)[0]))
    return f_ring, u_f


def compliance_with_ring(c: float, u_c: float, f_ring: float, u_f: float) -> tuple[float, float]:
    """The link's compliance from the harmonics' trend (c, u_c) and from its ring, c_ring = 1 / (2 pi f_ring)^2,
    combined by their weights; u widened by the Birge ratio when they disagree beyond their u.

    The ring's u: the ring frequency's (``u_f``, through c_ring's slope) and RING_RESONANCE_U of c_ring for what
    the ring is (a damped ring runs at sqrt(1 - zeta^2) of the resonance that amplifies the harmonics)."""
    c_ring = 1.0 / (2 * np.pi * f_ring) ** 2
    u_ring = c_ring * float(np.hypot(2 * u_f / f_ring, RING_RESONANCE_U))
    w_trend, w_ring = 1.0 / u_c**2, 1.0 / u_ring**2
    c_both = (w_trend * c + w_ring * c_ring) / (w_trend + w_ring)
    chi2 = (c - c_ring) ** 2 / (u_c**2 + u_ring**2)
    return float(c_both), float(np.sqrt(max(chi2, 1.0) / (w_trend + w_ring)))


def _crank_locked_lines(step: StepResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The crank-motion fit's residuals at whole multiples m of the crank's rate above the fitted harmonics, up to
    0.4 of the sampling rate: (m, amplitude m/s^2, power over the local noise: chi-square(2) under noise alone).

    Each line is fitted on the fitted crank angle (cos m phi, sin m phi: a line stays a line when the speed moves);
    its noise is the residual spectrum's median level within the crank's rate of it (the other lines removed), so a
    coloured sensor's noise is judged where the line is."""
    motion, t = step.state.motion, step.state.times
    f, rate, n = step.frequency_hz.value, step.state.rate, step.state.times.size
    span = n / rate
    top = int(min(np.floor(0.4 * rate / f), 4 * motion.harmonics + 16))
    orders = np.arange(motion.harmonics + 1, top + 1)
    if orders.size == 0:
        return orders, np.zeros(0), np.zeros(0)
    tau = (t - 0.5 * (t[0] + t[-1])) / motion.half_span
    phi = np.polynomial.chebyshev.chebval(tau, np.concatenate([[0.0], motion.coefficients]))
    basis = np.column_stack([g(m * phi) for m in orders for g in (np.cos, np.sin)])
    coef = np.linalg.lstsq(basis, motion.residuals, rcond=None)[0].reshape(-1, 2)
    power = np.abs(np.fft.rfft(motion.residuals - basis @ coef.ravel())) ** 2 / n
    bins = np.fft.rfftfreq(n, 1.0 / rate)
    score = np.zeros(orders.size)
    for k, m in enumerate(orders):
        # within the crank's rate (the other lines are removed) and at least 6 bins, the line's own 1.5 bins left out
        near = (np.abs(bins - m * f) < max(f, 6.0 / span)) & (np.abs(bins - m * f) > 1.5 / span)
        level = float(np.median(power[near])) / np.log(2) if near.any() else 0.0   # median of an exponential
        score[k] = float(coef[k] @ coef[k]) / (2 * level / n) if level > 0 else 0.0
    return orders, np.hypot(coef[:, 0], coef[:, 1]), score


def name_crank_locked_ripple(steps: list[StepResult]) -> str | None:
    """A speed ripple at a fixed multiple of the crank's rate (a motor's cogging, a gear's or a belt's teeth): named,
    with its size, when the steps agree on it.

    The crank angle phi - eps sin(N phi) moves the slider's n-th harmonic d_n into lines of d_n n eps / 2 at
    (N +- n) times the crank's rate: from the 1st, a pair at N - 1 and N + 1, each of acceleration
    ((N +- 1) omega)^2 r eps / 2.  Per step without play, the pair of crank-locked lines above the fitted harmonics
    (``_crank_locked_lines``) is tested for every N at FALSE_ALARM over all N and steps, and must hold
    CRANK_LOCKED_SHARE of those lines' power above the noise; named when CRANK_LOCKED_STEPS steps or more agree on N.
    Each step's eps is the mean of the pair's, and its speed ripple N eps (relative, peak).  The lines lie above the
    fitted harmonics, and the 2nd harmonic's sidebands (N +- 2) on the 4th and up, so the radius is untouched for N
    of 4 or more; the residuals they correlate are in u already (the sandwich).  Returns the warning, None when
    nothing is seen.
    """
    candidates = [i for i, s in enumerate(steps) if s.state is not None and s.state.times is not None
                  and not s.backlash and not s.link_ringing]
    found: dict[int, list[tuple[int, float, float]]] = {}
    tried = []
    for i in candidates:
        orders, amps, score = _crank_locked_lines(steps[i])
        pairs = [(int(m + 1), k) for k, m in enumerate(orders[:-2]) if orders[k + 2] == m + 2]
        tried.append((i, orders, amps, score, pairs))
    n_tests = max(sum(len(p) for *_, p in tried), 1)
    for i, orders, amps, score, pairs in tried:
        if not pairs:
            continue
        excess = float(np.sum(np.maximum(score - 2.0, 0.0)))
        n_best, k = max(pairs, key=lambda nk: score[nk[1]] + score[nk[1] + 2])
        pair = score[k] + score[k + 2]
        if stats.chi2.sf(pair, 4) * n_tests >= FALSE_ALARM or pair - 4.0 < CRANK_LOCKED_SHARE * excess:
            continue
        step = steps[i]
        omega2, radius = (2 * np.pi * step.frequency_hz.value) ** 2, step.radius_m.value
        eps = float(np.mean([2 * amps[j] / ((orders[j] ** 2) * omega2 * radius) for j in (k, k + 2)]))
        found.setdefault(n_best, []).append((i, eps, float(max(amps[k], amps[k + 2]))))
    if not found:
        return None
    per_turn, seen = max(found.items(), key=lambda item: len(item[1]))
    if len(seen) < CRANK_LOCKED_STEPS:
        return None
    for i, eps, _ in seen:
        steps[i] = replace(steps[i], crank_locked_per_turn=per_turn, crank_locked_ripple=per_turn * eps)
    sizes = sorted((steps[i].frequency_hz.value, per_turn * eps) for i, eps, _ in seen)
    return (f"the motor's speed ripples {per_turn} times per turn, locked to the crank (cogging, or a gear's or a "
            f"belt's teeth): lines at {per_turn - 1} and {per_turn + 1} times the crank's rate of up to "
            f"{max(a for *_, a in seen):.2g} m/s^2 in {len(seen)} of {len(steps)} steps, a speed ripple of "
            f"{100 * sizes[0][1]:.2g} % at {sizes[0][0]:.3g} Hz to {100 * sizes[-1][1]:.2g} % at {sizes[-1][0]:.3g} Hz; "
            "it leaves the radius alone (its lines lie above the fitted "
            "harmonics) and the residuals it correlates are in u")


def mark_rolloff(steps: list[StepResult]) -> float | None:
    """Flag steps beyond the motor's limit; return the roll-off (Hz), None if the motor followed every step.

    A step is beyond the limit when its speed wandered within the record, or
    it fell more than SPEED_SHORTFALL short of its command, or (without
    commanded speeds) it did not turn faster than the fastest step before it
    while the schedule rises.  A speed controller's scale is rarely exact
    (the paper's 100 % is "theoretically" 800 rpm), so "short" is judged
    against the best measured/commanded ratio of all steps, not against 1.
    A step whose speed wandered is beyond the limit only when it is among the
    fastest and at least two steady steps run below it (a motor hunting at its
    top); a motor that wanders at every speed is followed by the fit instead
    (its steps keep their radius, with the wider u that costs).
    The roll-off is the fastest mean speed seen in any step: where the motor
    tops out.
    """
    by_speed = sorted(steps, key=lambda s: s.frequency_hz.value)
    top = len(by_speed)
    while top > 0 and by_speed[top - 1].speed_unsteady:
        top -= 1
    # a steady step below speaks against a ripple only if it would have shown it: a drive's ripple of one
    # relative size at one rate moves the angle by spread / (2 f_ripple), in proportion to the speed, so the
    # slow steps' sidebands are the smallest, and a ripple faster than their crank is not followed at all
    # (motion_fit); counted without this, a 1 % wobble at 5 Hz seen only from 8 Hz up "topped out" the motor
    hunting = by_speed[top:]
    if sum(1 for s in by_speed[:top] if not s.speed_unsteady and all(_would_show(s, h) for h in hunting)) >= 2:
        for step in hunting:
            step.motor_limited = True
    ratios = [s.frequency_hz.value / s.commanded_hz for s in steps if s.commanded_hz]
    best_ratio = max(ratios) if ratios else None
    best = -np.inf
    for step in steps:
        f = step.frequency_hz.value
        if step.commanded_hz and f < step.commanded_hz * best_ratio * (1 - SPEED_SHORTFALL):
            step.motor_limited = True
        if step.commanded_hz is None and np.isfinite(best) and f < best * (1 + SPEED_SHORTFALL / 2):
            step.motor_limited = True
        if not step.motor_limited:
            best = max(best, f)
    if not any(s.motor_limited for s in steps):
        return None
    return float(max(s.frequency_hz.value for s in steps))


def budget_unfollowed_ripple(steps: list[StepResult]) -> None:
    """A speed ripple the faster steps followed, at steps that could not follow or show it: a Type B term.

    A relative ripple eps (peak to peak) at f_m moves the crank angle by dphi = f eps / (2 f_m), in proportion to
    the speed, and puts sidebands of A_k k dphi / 2 at k f +- f_m around each harmonic.  A step turning slower
    than the ripple (or within a resolution bin of it) cannot follow it (motion_fit), and a sideband within a
    resolution bin (1 / record) of a fitted harmonic j f is taken for that harmonic: a 1 % ripple at 5 Hz put
    the 2nd harmonic's lower sideband (4 Hz) on the 1st of a 4.5 Hz step, 0.2 % of the radius (14 um, 5 u).
    The ripple is the largest relative one the followed steps show; a steady step that would have shown it
    (_would_show) keeps its u.  Each such step's radius takes the sum of the sidebands on its 1st harmonic
    (relative), its 2nd harmonic's share likewise (check_compliance reads it), and its mean speed the angle's
    swing between the record's ends, sqrt(2) dphi / (2 pi T).
    """
    followed = [s for s in steps if s.speed_unsteady and s.speed_ripple_hz > 0]
    if not followed:
        return
    source = max(followed, key=lambda s: s.speed_spread_hz / s.frequency_hz.value)
    eps, rate = source.speed_spread_hz / source.frequency_hz.value, source.speed_ripple_hz
    for i, step in enumerate(steps):
        if step.speed_unsteady or step.state is None or _would_show(step, source):
            continue
        f = step.frequency_hz.value
        span = step.n_samples / step.state.rate
        dphi = f * eps / (2 * rate)
        amps = np.asarray(step.harmonic_amplitudes.value, dtype=float)
        share = np.zeros(3)   # relative error on harmonics 1 and 2 (index 1, 2)
        for k, a_k in enumerate(amps, start=1):
            for sideband in (abs(k * f - rate), k * f + rate):
                for j in (1, 2):
                    if j <= amps.size and abs(sideband - j * f) < 1.0 / span:
                        share[j] += a_k * k * dphi / 2 / amps[j - 1]
        u_r = step.radius_m.value * share[1]
        u_f = float(np.sqrt(2) * dphi / (2 * np.pi * span))
        u_radius = float(np.hypot(step.radius_m.uncertainty, u_r))
        u_freq = float(np.hypot(step.frequency_hz.uncertainty, u_f))
        common = float(np.hypot(step.radius_play_uncertainty_m, u_r))
        radius_dof = dof_with_play(u_radius, common, step.radius_dof)
        frequency_dof = dof_with_play(u_freq, u_f, step.frequency_dof)
        steps[i] = replace(step, radius_m=Estimate(step.radius_m.value, u_radius, "m"),
                           ratio=Estimate(step.ratio.value, u_radius / step.state.crank_radius, "1"),
                           frequency_hz=Estimate(f, u_freq, "Hz"), radius_dof=radius_dof,
                           radius_k=coverage_factor(radius_dof), frequency_dof=frequency_dof,
                           frequency_k=coverage_factor(frequency_dof), ripple_radius_uncertainty_m=float(u_r),
                           ripple_frequency_uncertainty_hz=u_f, ripple_second_harmonic_share=float(share[2]),
                           notes=[*step.notes, f"{step.where}: the faster steps show a speed ripple of "
                                  f"{100 * eps:.2g} % at {rate:.3g} Hz, which this step cannot follow (it turns "
                                  f"{'slower' if f <= rate else 'hardly faster'}): its sidebands' share is in u"])


def _would_show(steady: StepResult, wandering: StepResult) -> bool:
    """Whether ``steady`` would have been found unsteady had its speed rippled as ``wandering``'s did (the same
    relative spread at the same rate): the rate below its crank's, and the ripple's sidebands, A_1 times half
    the angle's swing, at least RIPPLE_VISIBLE times the step's u(A_1)."""
    rate = wandering.speed_ripple_hz
    if not (rate > 0 and rate < steady.frequency_hz.value):
        return False
    spread = wandering.speed_spread_hz / wandering.frequency_hz.value * steady.frequency_hz.value
    sideband = steady.amplitude.value * spread / (2 * rate) / 2
    return bool(sideband >= RIPPLE_VISIBLE * steady.amplitude.uncertainty)


def judge_clearance(steps: list[StepResult], crank_radius: float, clearance: float, scale_u: float = 0.0) -> None:
    """Flag each step the motor followed whose radius is outside the caliper radius +- clearance, by one
    test at CLEARANCE_ALPHA family-wise over those steps (the verdict, on their mean, is a test of its own).
    ``scale_u``: the profile's relative u of the scale along the motion (``profile_scale_u``), in each test."""
    judged = [s for s in steps if not s.motor_limited]
    for s in judged:
        radius, dof = s.radius_m, s.radius_dof
        if scale_u > 0:   # a Type B term known exactly: Welch-Satterthwaite scales the dof up
            u = float(np.hypot(radius.uncertainty, scale_u * radius.value))
            dof = dof * (u / s.radius_m.uncertainty) ** 4 if s.radius_m.uncertainty > 0 else float("inf")
            radius = Estimate(radius.value, u, "m")
        k = clearance_k(len(judged), dof)
        s.within_clearance = not outside_clearance(radius, crank_radius, clearance, k)
        s.clearance_k = k


def profile_scale_u(steps: list[StepResult], correction: Correction | None) -> float:
    """Relative u of the scale the verified profile gives the motion (0 for raw data).

    The radius is A_1 / omega^2 of the calibrated signal along the axis of motion, so the profile's own u of
    that scale (its gain u, u(g) included) moves every step's radius alike: whether the static calibration
    holds under motion can only be judged against both uncertainties (a GUM normalised error), else a profile
    honest about its u(g) "does not hold" against a motion measured ten times finer.  Common to the steps:
    added once to the mean and to each step's test, never to the weights.  The axis: the steps' PCA axes,
    signs aligned, averaged."""
    axes = [np.asarray(s.axis, dtype=float) for s in steps if len(s.axis) == 3]
    if correction is None or not axes:
        return 0.0
    axis = sum(a if a @ axes[0] >= 0 else -a for a in axes)
    return correction.scale_uncertainty(axis)


def combine_radius(steps: list[StepResult]) -> tuple[Estimate, float, int, list[int], float]:
    """Weighted mean radius over the steps the motor followed steadily, and the effective dof of its u^2.

    Weights and chi-square use each step's statistical uncertainty; that part
    is inflated by the Birge ratio sqrt(chi2 / dof) when the steps scatter more
    than it allows (a systematic effect such as a gain error shows as scatter
    too, and must not look precise).  The backlash share of the uncertainty is
    the same play in every step, so it is added once, not averaged down.
    The dof (``mean_dof``) is that of the steps' statistical u^2 (the Birge
    ratio only ever widens it: kept as the conservative choice, not taken as
    a further estimate).
    """
    used = [s for s in steps if not s.motor_limited]
    if not used:
        return Estimate(float("nan"), float("nan"), "m"), float("nan"), 0, [], float("inf")
    r = np.array([s.radius_m.value for s in used])
    # the play's and the compliance correction's shares are the same in every step: added once, not averaged down
    u_play = np.hypot([s.radius_play_uncertainty_m for s in used], [s.radius_compliance_uncertainty_m for s in used])
    u = np.sqrt(np.maximum(np.array([s.radius_m.uncertainty for s in used]) ** 2 - u_play**2, 0.0))
    w = 1 / u**2
    mean = float(np.sum(w * r) / np.sum(w))
    u_mean = float(np.sqrt(1 / np.sum(w)))
    dof = len(used) - 1
    chi2 = float(np.sum(w * (r - mean) ** 2))
    if dof > 0 and chi2 > dof:
        u_mean *= float(np.sqrt(chi2 / dof))
    u_common = float(np.sum(w * u_play) / np.sum(w))
    u_total = float(np.hypot(u_mean, u_common))
    nu = dof_with_play(u_total, u_common, mean_dof(used, u))
    return Estimate(mean, u_total, "m"), chi2, dof, [s.index for s in used], nu


def mean_dof(used: list[StepResult], u: np.ndarray) -> float:
    """Effective dof of the weighted mean's variance 1 / sum(1 / u_i^2) (u: the steps' statistical u).

    Its gradient in each step's variance is (u_mean / u_i)^4.  Steps whose u is from the pooled bands share
    those bands' estimates: their gradients in the band powers are summed before the variance is taken
    (one pooled model per sampling rate); every other step's u^2 is its own estimate, with its own dof.
    """
    u_mean2 = 1.0 / float(np.sum(1.0 / u**2))
    variance, shared = 0.0, {}
    for step, u_i in zip(used, u, strict=True):
        weight = (u_mean2 / u_i**2) ** 2
        checks = step.checks
        if checks is not None and checks.pooled_model is not None and checks.radius_shares is not None:
            _, gradient = checks.pooled_model.variance_gradient(checks.pooled_index, checks.radius_shares)
            model_id = id(checks.pooled_model)
            total = shared.get(model_id, (checks.pooled_model, 0.0))[1]
            shared[model_id] = (checks.pooled_model, total + weight * gradient)
        else:
            dof = float(checks.dof) if checks is not None else float("inf")
            if np.isfinite(dof):
                variance += weight**2 * 2.0 * u_i**4 / dof
    for model, gradient in shared.values():
        variance += model.gradient_variance(gradient)
    return satterthwaite_dof(u_mean2, variance)


def verdict_for(radius: Estimate, crank_radius: float, clearance: float, n_used: int,
                k: float = 2.0) -> tuple[str, str]:
    """Judge the weighted mean radius against the caliper radius +- clearance at k (t_p of its effective dof,
    2 at large dof).

    Single steps outside the bounds are reported per step (and in warnings)
    but do not decide alone: with several steps at k = 2 one of them falls
    outside by chance often, while a real dynamic error (a gain off, a
    frequency-dependent loss) moves the mean or inflates its Birge-scaled
    uncertainty.
    """
    if n_used < 2:
        return "inconclusive", f"only {n_used} step(s) where the motor followed steadily: need at least 2"
    lo, hi = crank_radius - clearance, crank_radius + clearance
    bounds = f"[{lo * 1e3:.3f}, {hi * 1e3:.3f}] mm" if clearance > 0 else f"{crank_radius * 1e3:.3f} mm"
    value_mm, u_mm = format_value(radius.value * 1e3, radius.uncertainty * 1e3)   # u to 2 digits, not 0.0000
    measured = f"{value_mm} mm (u {u_mm} mm at k = 1)"
    if abs(radius.value - crank_radius) > clearance + k * radius.uncertainty:
        return "does not hold", (f"radius from the measured motion {measured} lies outside the caliper radius "
                                 f"{bounds} by more than k u (k = {k:.2f})")
    return "holds", (f"radius from the measured motion {measured} agrees with the caliper radius {bounds} "
                     f"within k u (k = {k:.2f})")


# How the CLI and the verification screen label coverage_factors' keys (the JSON keeps the field names)
COVERAGE_FACTOR_LABELS = {"radius_k": "k (verdict, expanded U)", "steps[].radius_k": "k for U (per step)",
                          "steps[].clearance_k": "k (in clearance)"}


def coverage_factors(steps: list[StepResult], radius_k: float, radius_dof: float) -> dict[str, str]:
    """What each coverage factor a slider-crank result states is, and why they differ (for the JSON, the CLI
    and the verification screen alike: one text).  Three k, three questions: the combined radius's U and the
    verdict (about 95 % for that one number), each step's own U (about 95 % for that step alone), and the
    per-step clearance flag (5 % over all the steps judged together, so it is larger)."""
    judged = [s for s in steps if not s.motor_limited]
    dof = _plain_dof(radius_dof)
    level = f"{100 * COVERAGE_PROBABILITY:.2f} %"
    out = {"radius_k": (f"k = {radius_k:.2f}: the combined radius's U and the verdict, Student's t for {level} on "
                        + (f"its effective degrees of freedom (nu_eff {dof:.0f})" if dof is not None else
                           "a u that rests on much data (the normal's 2.00)")),
           "steps[].radius_k": (f"each step's own U, Student's t for {level} on that step's nu_eff (2.00 when its u "
                                "rests on much data); it is above the verdict's k when a step's u rests on fewer "
                                "data than the combined radius's")}
    if judged:
        ks = [s.clearance_k for s in judged]
        span = f"{min(ks):.2f}" if max(ks) - min(ks) < 0.005 else f"{min(ks):.2f}-{max(ks):.2f}"
        out["steps[].clearance_k"] = (
            f"k = {span}: each step's 'in clearance' flag, one test at {100 * CLEARANCE_ALPHA:g} % over the "
            f"{len(judged)} step{'s' if len(judged) != 1 else ''} judged together (Sidak, Student's t on the step's "
            "nu_eff): larger than the verdict's k so that sound steps raise a false 'outside' in "
            f"{100 * CLEARANCE_ALPHA:g} % of runs, not in each step's 5 %")
    return out


def step_warnings(steps: list[StepResult], rolloff: float | None) -> list[str]:
    """What the operator should know about single steps: outside the clearance, backlash, wandering speed, roll-off."""
    warnings = []
    for s in steps:
        if not s.within_clearance and not s.motor_limited:
            warnings.append(
                f"{s.where}: radius {s.radius_m.value * 1e3:.4f} +- {s.radius_m.uncertainty * 1e3:.4f} mm is "
                f"outside the caliper radius +- clearance (k = {s.clearance_k:.2f}: a {100 * CLEARANCE_ALPHA:g} % "
                "test over all steps judged)"
            )
        if s.link_ringing:
            warnings.append(f"{s.where}: a phase-locked ring at the dead centres of up to {s.knock_peak:.2g} m/s^2 at "
                            f"{s.ring_hz:.0f} Hz: the rail's friction reversing there rings the link at its own "
                            "resonance, the one the harmonics' trend with speed admits, not play (a knock would ring at "
                            "its contact's frequency); its share is in u(radius)")
        if s.backlash:
            where = ("at the dead centres" if s.take_up_deg == 0 else
                     f"{s.take_up_deg:.0f} deg after each dead centre, where the force through the link reverses")
            warnings.append(f"{s.where}: backlash (play taken up {where}): a phase-locked "
                            f"residual of up to {s.knock_peak:.2g} m/s^2 there; the play's share is in u(radius)")
        if s.speed_unsteady:
            warnings.append(f"{s.where}: the speed wandered by {s.speed_spread_hz:.3g} Hz "
                            f"({100 * s.speed_spread_hz / s.frequency_hz.value:.1f} %) within the record: followed by "
                            f"a speed profile of order {s.speed_order}, u widened accordingly")
        warnings.extend(s.notes)
    if rolloff is not None:
        limited = ", ".join(s.where for s in steps if s.motor_limited)
        warnings.append(
            f"the motor tops out near {rolloff:.2f} Hz: {limited} did not run the intended steady speed "
            "(left out of the radius)"
        )
    return warnings


def frequency_response(steps: list[StepResult]) -> dict[str, np.ndarray]:
    """Arrays for the frequency response plot (paper Fig. 7)."""
    return {
        "frequency_hz": np.array([s.frequency_hz.value for s in steps]),
        "amplitude": np.array([s.amplitude.value for s in steps]),
        "amplitude_uncertainty": np.array([s.amplitude.uncertainty for s in steps]),
        "model_amplitude": np.array([s.model_amplitude for s in steps]),
        "model_lower": np.array([s.model_amplitude_bounds[0] for s in steps]),
        "model_upper": np.array([s.model_amplitude_bounds[1] for s in steps]),
        "radius_m": np.array([s.radius_m.value for s in steps]),
        "radius_uncertainty_m": np.array([s.radius_m.uncertainty for s in steps]),
    }


def verify_steps(steps: list[StepResult], crank_radius: float, rod_length: float, clearance: float,
                 profile: str | None = None, correction: Correction | None = None) -> CalibrationResult:
    """The verification over all analysed steps: roll-off, weighted radius, verdict.

    No correction comes out (a verification judges one); the radius from the
    motion is the parameter, the verdict and the per-step table are in
    ``details`` and the frequency response in ``arrays``.
    """
    if not steps:
        raise DataError("no steps were captured", "capture at least two motor speed steps")
    pool_noise(steps)
    check_neighbours(steps)
    budget_unfollowed_ripple(steps)
    compliance = check_compliance(steps)
    compliance_check = compliance_status(steps, compliance)
    cogging = name_crank_locked_ripple(steps)
    rolloff = mark_rolloff(steps)
    scale_u = profile_scale_u(steps, correction)
    judge_clearance(steps, crank_radius, clearance, scale_u)
    radius, chi2, dof, used, radius_dof = combine_radius(steps)
    u_scale = scale_u * abs(radius.value) if np.isfinite(radius.value) else 0.0
    if u_scale > 0:
        # a Type B term of the profile's own, known exactly here: Welch-Satterthwaite scales the dof up
        u_total = float(np.hypot(radius.uncertainty, u_scale))
        radius_dof = radius_dof * (u_total / radius.uncertainty) ** 4 if radius.uncertainty > 0 else float("inf")
        radius = Estimate(radius.value, u_total, radius.unit)
    radius_k = coverage_factor(radius_dof)
    verdict, reason = verdict_for(radius, crank_radius, clearance, len(used), radius_k)
    if profile is None and correction is None:
        reason += ("; no profile was applied, so this judges the sensor's nominal scale, not a calibration "
                   "(give the profile to verify)")
    geometry = {"crank_radius_m": crank_radius, "rod_length_m": rod_length, "lambda": crank_radius / rod_length,
                "clearance_m": clearance, "profile": profile}
    scale = {"profile_scale_u_rel": scale_u, "radius_profile_u_m": u_scale}
    return CalibrationResult(
        procedure="slider-crank",
        method="sine fit with harmonics per step, radius from the first harmonic",
        model="A_1 = r omega^2",
        correction=None,
        parameters={"radius": radius},
        parameter_meaning=("the crank radius the calibrated motion shows, from each step's first harmonic "
                           "A_1 = r omega^2, combined over the steps: a verification of a correction, not one"),
        quality={"radius_chi2": chi2, "radius_dof": dof, "n_steps": len(steps), "radius_k": radius_k,
                 "compliance_check": compliance_check},
        arrays=frequency_response(steps),
        settings=geometry,
        warnings=([compliance["warning"]] if compliance else []) + ([cogging] if cogging else [])
        + step_warnings(steps, rolloff),
        details={**geometry, **scale, "steps": [s.to_json_dict() for s in steps], "radius_m": radius.to_dict(),
                 "radius_chi2": chi2, "radius_dof": dof, "radius_nu_eff": _plain_dof(radius_dof), "radius_k": radius_k,
                 # what a certificate states U of the radius with (report.html): the same k the verdict used
                 "coverage_factor": radius_k, "coverage_dof": _plain_dof(radius_dof),
                 "coverage_factors": coverage_factors(steps, radius_k, radius_dof),
                 "used_steps": used, "rolloff_hz": rolloff,
                 "compliance": None if compliance is None else {k: v for k, v in compliance.items() if k != "warning"},
                 "verdict": verdict, "verdict_reason": reason},
    )
