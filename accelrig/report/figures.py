"""Certificate figures, drawn with matplotlib (the ``report`` extra) into inline SVG.

Each figure keeps the arrays it plotted in ``series`` (tests compare them with
the result's own arrays, not pictures).  Axes are in physical units; each
title says what to look for.  A figure whose data the source does not carry is
not drawn: ``figures_for`` returns the reason instead, and the certificate
prints it.
"""

from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from accelrig.errors import AccelrigError
from accelrig.report.source import Source

# Dense scatter (a wheel run holds ~10^4 samples per axis) is embedded as a bitmap inside the SVG so a
# certificate stays small; axes, labels and sparse curves stay vector.
RASTER_ABOVE = 2000
AXES = ("x", "y", "z")


@dataclass
class Figure:
    key: str
    title: str
    caption: str
    svg: str = ""
    series: dict[str, np.ndarray] = field(default_factory=dict)


def require_matplotlib():
    """pyplot on the Agg backend, or an error naming the extra to install."""
    try:
        import matplotlib
    except ImportError:
        raise AccelrigError("figures need matplotlib, which is not installed",
                            "pip install 'accelrig[report]' (or --no-figures for a certificate without them)") from None
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    plt.rcParams.update({"svg.fonttype": "none", "font.size": 9, "axes.grid": True, "grid.alpha": 0.3,
                         "svg.hashsalt": "accelrig", "figure.dpi": 100})
    return plt


def _svg(fig) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None, "Creator": None})
    import matplotlib.pyplot as plt

    plt.close(fig)
    text = buf.getvalue()
    return text[text.index("<svg"):]   # drop the XML prolog and DOCTYPE: the SVG sits inside HTML


def _dense(n: int) -> bool:
    return n > RASTER_ABOVE


# ------------------------------------------------------------------ static


def static_series(src: Source) -> dict[str, np.ndarray]:
    """What the static figure shows: per pose, |a| - g before (nominal scale) and after the correction, the
    pose's mid time (s) when the source has it, and the fit residual per axis when the model has them.
    Pure numpy: the TUI draws the same arrays."""
    arrays, g = src.arrays, float(src.result["settings"].get("g", 9.80665))
    corr = src.result.get("correction")
    series: dict[str, np.ndarray] = {}
    if "pose_means" in arrays and corr is not None:
        means = np.asarray(arrays["pose_means"], dtype=float)
        c, b = np.asarray(corr["matrix"]), np.asarray(corr["bias"])
        series["pose"] = np.arange(1, len(means) + 1)
        series["before"] = np.linalg.norm(means, axis=1) - g
        series["after"] = np.linalg.norm((means - b) @ c.T, axis=1) - g
    else:
        rows = [r for r in src.details.get("poses", []) if "magnitude_residual" in r]
        if not rows:
            raise LookupError("the source carries neither the pose means nor the per-pose table "
                              "(a profile keeps neither: render the certificate from the result)")
        series["pose"] = np.arange(1, len(rows) + 1)
        series["after"] = np.array([r["magnitude_residual"] for r in rows])
    times = np.asarray(arrays.get("pose_times", []), dtype=float)
    if times.ndim == 2 and times.shape == (series["pose"].size, 2):
        series["pose_time_s"] = times.mean(axis=1)
    if "pose_residuals" in arrays:
        series["residuals"] = np.asarray(arrays["pose_residuals"], dtype=float)
    return series


def static_figure(src: Source) -> Figure:
    """|g| error per pose before and after the correction; residual per pose and axis when the model has them."""
    plt = require_matplotlib()
    series = static_series(src)
    has_vectors = "residuals" in series
    fig, axs = plt.subplots(1, 2 if has_vectors else 1, figsize=(9 if has_vectors else 5.5, 3.2), squeeze=False)
    ax = axs[0, 0]
    width = 0.38
    if "before" in series:
        ax.bar(series["pose"] - width / 2, series["before"], width, label="before (nominal scale)", color="0.6")
    ax.bar(series["pose"] + (width / 2 if "before" in series else 0), series["after"], width,
           label="after the correction", color="C0")
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xlabel("pose (order used)")
    ax.set_ylabel("|a| - g  (m/s²)")
    ax.set_xticks(series["pose"])
    ax.set_title("Gravity magnitude per pose: after should sit near 0", fontsize=9)
    ax.legend(fontsize=7)
    if has_vectors:
        res = series["residuals"]
        ax = axs[0, 1]
        for k in range(3):
            ax.bar(series["pose"] + (k - 1) * 0.27, res[:, k], 0.27, label=AXES[k])
        ax.axhline(0, color="k", lw=0.8)
        ax.set_xlabel("pose (order used)")
        ax.set_ylabel("fit residual (m/s²)")
        ax.set_xticks(series["pose"])
        ax.set_title("Residual per pose and axis: no pose should stand out", fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return Figure("static", "Static poses", "Gravity magnitude error of each still pose with the nominal scale "
                  "(before) and with the certified correction (after).", _svg(fig), series)


# ------------------------------------------------------------------ wheel


def wheel_series(src: Source) -> dict[str, np.ndarray]:
    """What the wheel figure shows: the half-turn speeds and the fitted law (s, rad/s), the acceleration
    residuals against time (s) and the wheel's angle (degrees, when the result has it), and their spectrum."""
    a = src.arrays
    if "speed_time" not in a:
        raise LookupError("the source carries no wheel arrays (a profile or a saved --json result keeps none: "
                          "render the certificate from the result)")
    series = {k: np.asarray(a[k], dtype=float) for k in ("speed_time", "speed_samples", "speed_fit",
                                                         "speed_residuals", "t", "residuals", "angle_deg")
              if k in a}
    series["spectrum_frequency"], series["spectrum"] = residual_asd(series["t"], series["residuals"])
    return series


def wheel_figure(src: Source) -> Figure:
    plt = require_matplotlib()
    series = wheel_series(src)
    fig = plt.figure(figsize=(9, 8.2))
    grid = fig.add_gridspec(3, 2)
    ax = fig.add_subplot(grid[0, 0])
    ax.plot(series["speed_time"], series["speed_samples"], ".", ms=3, label="half turns")
    ax.plot(series["speed_time"], series["speed_fit"], "-", lw=1.2, label="fitted cubic speed law")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("angular speed (rad/s)")
    ax.set_title("Speed law: points should follow the curve", fontsize=9)
    ax.legend(fontsize=7)
    ax = fig.add_subplot(grid[0, 1])
    ax.plot(series["speed_time"], series["speed_residuals"], ".", ms=3)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("speed residual (rad/s)")
    ax.set_title("Speed residuals: no trend expected", fontsize=9)
    ax = fig.add_subplot(grid[1, 0])
    t, res = series["t"], series["residuals"]
    for k in range(res.shape[1]):
        ax.plot(t, res[:, k], ",", label=AXES[k], rasterized=_dense(t.size), alpha=0.6)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("acceleration residual (m/s²)")
    ax.set_title("Residuals over the run: flat noise, no drift", fontsize=9)
    ax.legend(fontsize=7, markerscale=20)
    ax = fig.add_subplot(grid[1, 1])
    if "angle_deg" in series:
        for k in range(res.shape[1]):
            ax.plot(series["angle_deg"], res[:, k], ",", label=AXES[k], rasterized=_dense(t.size), alpha=0.6)
        ax.set_xlim(0, 360)
        ax.set_xticks(range(0, 361, 90))
        ax.set_xlabel("wheel angle (degrees)")
        ax.set_ylabel("acceleration residual (m/s²)")
        ax.set_title("Residuals against the angle: no wave (a wave: radius, tilt or mounting off)", fontsize=9)
    else:
        ax.text(0.5, 0.5, "the result keeps no wheel angle", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
    ax = fig.add_subplot(grid[2, :])
    freq, spectrum = series["spectrum_frequency"], series["spectrum"]
    for k in range(res.shape[1]):
        ax.semilogy(freq[1:], spectrum[1:, k], lw=0.8, label=AXES[k])
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("residual ASD ((m/s²)/√Hz)")
    ax.set_title("Residual spectrum: white, no peak at the turn rate", fontsize=9)
    fig.tight_layout()
    return Figure("wheel", "Wheel", "Speed of each half turn against the fitted cubic law, and the acceleration "
                  "residuals over time, over the wheel's angle and over frequency.", _svg(fig), series)


def residual_asd(t: np.ndarray, res: np.ndarray, segments: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectral density of the residuals, averaged over ``segments`` Hann-windowed,
    half-overlapping pieces (Welch), so a line stands out of the noise instead of hiding in its scatter."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    n = max(16, 2 * t.size // (segments + 1))
    n = min(n, t.size)
    window = np.hanning(n)
    starts = range(0, t.size - n + 1, max(n // 2, 1))
    power = np.zeros((n // 2 + 1, res.shape[1]))
    for s in starts:
        piece = res[s:s + n] - res[s:s + n].mean(axis=0)
        power += np.abs(np.fft.rfft(piece * window[:, None], axis=0)) ** 2
    power *= 2 * dt / (np.sum(window**2) * len(starts))
    return np.fft.rfftfreq(n, dt), np.sqrt(power)


# ------------------------------------------------------------------ slider-crank


def slider_crank_series(src: Source) -> dict[str, np.ndarray]:
    """What the slider-crank figure shows, per step: frequency (Hz), measured and model amplitude with the
    clearance band (m/s²), the radius from the motion (m), each with u (k = 1)."""
    d = src.details
    if not d.get("steps"):
        raise LookupError("the source carries no per-step table (a profile keeps none)")
    steps = d["steps"]
    return {
        "frequency_hz": np.array([s["frequency_hz"]["value"] for s in steps]),
        "amplitude": np.array([s["amplitude"]["value"] for s in steps]),
        "amplitude_uncertainty": np.array([s["amplitude"]["uncertainty"] for s in steps]),
        "model_amplitude": np.array([s["model_amplitude"] for s in steps]),
        "model_lower": np.array([s["model_amplitude_bounds"][0] for s in steps]),
        "model_upper": np.array([s["model_amplitude_bounds"][1] for s in steps]),
        "radius_m": np.array([s["radius_m"]["value"] for s in steps]),
        "radius_uncertainty_m": np.array([s["radius_m"]["uncertainty"] for s in steps]),
        # each step's coverage factor (Student's t on its u's effective dof; 2 in results saved before it)
        "coverage_factor": np.array([s.get("radius_k", 2.0) for s in steps]),
    }


def slider_crank_figure(src: Source) -> Figure:
    plt = require_matplotlib()
    d = src.details
    series = slider_crank_series(src)
    f = series["frequency_hz"]
    order = np.argsort(f)
    fig, axs = plt.subplots(1, 2, figsize=(9, 3.4))
    ax = axs[0]
    ax.fill_between(f[order], series["model_lower"][order], series["model_upper"][order], color="C1", alpha=0.25,
                    label="model within the clearance")
    ax.plot(f[order], series["model_amplitude"][order], "-", color="C1", label="slider-crank model")
    k = series["coverage_factor"]
    k_label = f"k = {k[0]:.2f}" if np.ptp(k) < 0.005 else f"k = {k.min():.2f}-{k.max():.2f}"
    ax.errorbar(f, series["amplitude"], yerr=k * series["amplitude_uncertainty"], fmt="o", ms=4, color="C0",
                label=f"measured (U, {k_label})")
    ax.set_xlabel("crank frequency (Hz)")
    ax.set_ylabel("first-harmonic amplitude (m/s²)")
    ax.set_title("Amplitude vs frequency: points should lie inside the band", fontsize=9)
    ax.legend(fontsize=7)
    ax = axs[1]
    r0, clearance = d.get("crank_radius_m"), d.get("clearance_m") or 0.0
    if r0 is not None:
        ax.axhspan(1e3 * (r0 - clearance), 1e3 * (r0 + clearance), color="C1", alpha=0.25,
                   label="caliper radius ± clearance")
        ax.axhline(1e3 * r0, color="C1")
    ax.errorbar(f, 1e3 * series["radius_m"], yerr=1e3 * k * series["radius_uncertainty_m"], fmt="o", ms=4,
                label=f"radius from the motion (U, {k_label})")
    ax.set_xlabel("crank frequency (Hz)")
    ax.set_ylabel("crank radius (mm)")
    ax.set_title("Radius per step: should lie inside the clearance band", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return Figure("slider-crank", "Slider-crank verification", "Measured first-harmonic amplitude against the "
                  "slider-crank model, and the crank radius recovered from each step.", _svg(fig), series)


# ------------------------------------------------------------------ rotary


def rotary_sensitivity_series(src: Source) -> tuple[list[str], dict[str, np.ndarray]]:
    """Each test's sensitivity per sensor axis (counts per m/s², u at k = 1): the group ("sensor axis") of
    each row, and the arrays test, sensitivity, uncertainty."""
    d = src.details
    tests = d.get("tests")
    if tests is None and "sensitivity" in d:
        tests = [{"index": 1, "label": "test", "sensor": "sensor", **d}]   # numbered from 1, as campaigns
    if not tests:
        raise LookupError("the source carries no per-test table (a profile keeps none)")
    rows = [(t["index"], f"{t['sensor']} {axis}", s["value"], s["uncertainty"])
            for t in tests for axis, s in t["sensitivity"].items()]
    return [r[1] for r in rows], {"test": np.array([r[0] for r in rows]), "sensitivity": np.array([r[2] for r in rows]),
                                  "uncertainty": np.array([r[3] for r in rows])}


def rotary_figures(src: Source) -> list[Figure]:
    plt = require_matplotlib()
    d = src.details
    figures = []
    groups, series = rotary_sensitivity_series(src)
    fig, ax = plt.subplots(figsize=(6.5, 3.2))
    for group in dict.fromkeys(groups):
        sel = [i for i, g in enumerate(groups) if g == group]
        ax.errorbar(series["test"][sel], series["sensitivity"][sel], yerr=2 * series["uncertainty"][sel],
                    fmt="o", ms=4, label=group)
    ax.set_xlabel("test number")
    ax.set_ylabel("sensitivity (counts per m/s²)")
    ax.set_title("Sensitivity per test (U, k = 2): the same axis should agree", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    figures.append(Figure("rotary-sensitivity", "Sensitivity per test", "Sensitivity of each axis in each test, "
                          "with its expanded uncertainty.", _svg(fig), series))
    lines = [(sensor, axis, e["linearity"]) for sensor, axes in d.get("per_axis", {}).items()
             for axis, e in axes.items() if e.get("linearity")]
    if lines:
        fig, axs = plt.subplots(2, len(lines), figsize=(min(3.0 * len(lines), 12), 4.8), squeeze=False,
                                sharex="col", gridspec_kw={"height_ratios": [2, 1]})
        series = {}
        for col, (sensor, axis, lin) in enumerate(lines):
            q_i, q_o = np.asarray(lin["reference"]), np.asarray(lin["output"])
            x = np.linspace(0, q_i.max() * 1.05, 50)
            band = 2 * regression_band_sd(lin, x)
            key = f"{sensor}_{axis}"
            series[f"{key}_reference"], series[f"{key}_output"] = q_i, q_o
            series[f"{key}_residuals"] = q_o - (lin["intercept"] + lin["slope"] * q_i)
            series[f"{key}_band_x"], series[f"{key}_band"] = x, band
            ax = axs[0, col]
            ax.plot(q_i, q_o, "o", ms=4)
            ax.plot(x, lin["intercept"] + lin["slope"] * x, "-", lw=1)
            ax.set_ylabel("output (counts)")
            ax.set_title(f"{sensor} {axis}: on the line, R² = {lin['r_squared']:.5f}", fontsize=8)
            ax = axs[1, col]
            ax.fill_between(x, -band, band, color="C1", alpha=0.3, label="line, U (k = 2)")
            ax.plot(q_i, series[f"{key}_residuals"], "o", ms=4)
            ax.axhline(0, color="k", lw=0.8)
            ax.set_xlabel("reference amplitude (m/s²)")
            ax.set_ylabel("residual (counts)")
            if col == 0:
                ax.legend(fontsize=6)
        fig.tight_layout()
        figures.append(Figure("rotary-linearity", "Linearity", "Output amplitude against the reference "
                              "amplitude per sensor axis with the regression line; below, the residuals from "
                              "the line and the line's expanded uncertainty band (k = 2). Points scattered "
                              "around 0 without a curve mean a linear sensor.", _svg(fig), series))
    bland = d.get("bland_altman") or []
    if isinstance(bland, dict):
        bland = [{"test": 0, "label": "test", **bland}]
    if bland:
        series = {"test": np.array([b["test"] for b in bland]), "bias": np.array([b["bias"] for b in bland]),
                  "lower": np.array([b["lower_limit_of_agreement"] for b in bland]),
                  "upper": np.array([b["upper_limit_of_agreement"] for b in bland])}
        fig, ax = plt.subplots(figsize=(6.5, 3.0))
        ax.vlines(series["test"], series["lower"], series["upper"], color="C0", alpha=0.5,
                  label="limits of agreement (bias ± 1.96 sd)")
        ax.plot(series["test"], series["bias"], "o", color="C0", label="mean difference")
        ax.axhline(0, color="k", lw=0.8)
        ax.set_xlabel("test number")
        ax.set_ylabel("reference accelerometer − encoder (m/s²)")
        ax.set_title("Bland-Altman per test: limits should straddle 0", fontsize=9)
        ax.legend(fontsize=7)
        fig.tight_layout()
        figures.append(Figure("rotary-bland-altman", "Bland-Altman", "Agreement of the reference accelerometer "
                              "with the encoder's acceleration in each test.", _svg(fig), series))
    return figures


def regression_band_sd(line: dict, x: np.ndarray) -> np.ndarray:
    """Standard deviation of the fitted line at ``x``: s^2 (1/n + (x - mean)^2 / Sxx), from the points the
    regression was made of (the campaign keeps them) and its residual sd."""
    q_i = np.asarray(line["reference"], dtype=float)
    n = q_i.size
    sxx = float(np.sum((q_i - q_i.mean()) ** 2))
    return line["residual_sd"] * np.sqrt(1.0 / n + (np.asarray(x) - q_i.mean()) ** 2 / sxx)


# ------------------------------------------------------------------ noise


# One-sided white-noise densities from the datasheets (REFERENCES.md), ug/sqrt(Hz).
DATASHEET_DENSITY_UG = {"mpu9250": 300.0, "icm20948": 230.0}
G0 = 9.80665


def noise_figure(src: Source) -> Figure:
    """Allan deviation per axis: the measured curve when the source carries it (``accelrig noise --json``),
    the noise terms the certified figures imply (N/sqrt(2 tau), the bias-instability floor, K sqrt(tau/3)),
    and the datasheet's white-noise line for a known chip."""
    plt = require_matplotlib()
    noise = src.noise
    if not noise:
        raise LookupError("the source holds no noise figures (accelrig noise REC --profile P adds them)")
    measured = noise.get("arrays") or {}
    if "tau" in measured:
        tau = np.asarray(measured["tau"], dtype=float)
    else:
        tau = np.logspace(np.log10(2.0 / noise["rate"]), np.log10(max(noise["duration"] / 3, 10.0 / noise["rate"])),
                          60)
    series = {"tau_s": tau}
    fig, ax = plt.subplots(figsize=(6.5, 3.6))
    for k, axis in enumerate(AXES):
        figures = noise["axes"][axis]
        color = f"C{k}"
        if f"adev_{axis}" in measured:
            adev = np.asarray(measured[f"adev_{axis}"], dtype=float)
            err = np.asarray(measured.get(f"adev_{axis}_uncertainty", np.zeros_like(adev)), dtype=float)
            series[f"adev_{axis}"] = adev
            ax.errorbar(tau, adev, yerr=err, fmt="o", ms=3, color=color, label=f"{axis}: measured")
        white = figures["density"]["value"] / np.sqrt(2 * tau)
        series[f"white_{axis}"] = white
        ax.loglog(tau, white, ":", color=color, lw=1, label=f"{axis}: white noise (slope −½)")
        if figures.get("bias_instability"):
            floor = 0.664 * figures["bias_instability"]["value"]
            series[f"bias_instability_{axis}"] = np.full_like(tau, floor)
            ax.axhline(floor, color=color, ls="--", lw=0.8)
        if figures.get("random_walk"):
            walk = figures["random_walk"]["value"] * np.sqrt(tau / 3)
            series[f"random_walk_{axis}"] = walk
            ax.loglog(tau, walk, "-.", color=color, lw=0.8)
    chip = str(src.device.get("chip") or "").lower().replace("-", "")
    if chip in DATASHEET_DENSITY_UG:
        line = DATASHEET_DENSITY_UG[chip] * 1e-6 * G0 / np.sqrt(2 * tau)
        series["datasheet"] = line
        ax.loglog(tau, line, "k-", lw=1.2, label=f"{chip} datasheet, {DATASHEET_DENSITY_UG[chip]:g} µg/√Hz")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("averaging time τ (s)")
    ax.set_ylabel("Allan deviation (m/s²)")
    ax.set_title("Allan deviation: −½ white noise, flat bias instability (dashed), +½ random walk", fontsize=9)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    caption = ("Overlapping Allan deviation of the still recording with the noise terms of the certified figures."
               if "tau" in measured else
               "The Allan deviation terms the certified noise figures imply; the measured curve is not kept in "
               "the profile (give the certificate the curves with --noise NOISE.json from accelrig noise --json).")
    return Figure("noise", "Noise (Allan deviation)", caption, _svg(fig), series)


# ------------------------------------------------------------------ batch


def batch_figures(batch) -> list[Figure]:
    """Per quantity (and unit), one panel per axis: every device's value with U (k), the weighted mean, the
    mean of the devices; outliers in red.  ``series`` keeps the plotted values per axis."""
    plt = require_matplotlib()
    figures = []
    kinds = list(dict.fromkeys((g.quantity, g.unit) for g in batch.groups))
    for quantity, unit in kinds:
        groups = [g for g in batch.groups if (g.quantity, g.unit) == (quantity, unit)]
        n_dev = max(len(g.rows) for g in groups)
        fig, axs = plt.subplots(1, len(groups), figsize=(min(3.2 * len(groups), 9.5), 2.6 + 0.06 * n_dev),
                                squeeze=False)
        series: dict[str, np.ndarray] = {}
        for ax, g in zip(axs[0], groups, strict=True):
            x = np.arange(1, len(g.rows) + 1)
            values = np.array([j.entry.value for j in g.rows])
            expanded = batch.k * np.array([j.entry.u for j in g.rows])
            flagged = np.array([j.outlier for j in g.rows])
            series[f"{g.axis}_value"], series[f"{g.axis}_U"], series[f"{g.axis}_outlier"] = values, expanded, flagged
            ax.axhline(g.weighted_mean, color="C0", lw=1, label="weighted mean")
            ax.axhline(g.mean, color="C1", lw=1, ls="--", label="mean of the devices")
            ok = ~flagged
            ax.errorbar(x[ok], values[ok], yerr=expanded[ok], fmt="o", ms=3, color="C0", label=f"U (k = {batch.k:g})")
            if flagged.any():
                ax.errorbar(x[flagged], values[flagged], yerr=expanded[flagged], fmt="s", ms=4, color="C3",
                            label="outlier")
            ax.set_xticks(x)
            ax.set_xticklabels([j.entry.device for j in g.rows], rotation=90, fontsize=6)
            ax.set_ylabel(f"{quantity} {g.axis} ({'relative' if unit == '1' else unit})")
            ax.set_title(f"axis {g.axis}", fontsize=9)
        axs[0, 0].legend(fontsize=6)
        fig.suptitle(f"{quantity.capitalize()} per device: red squares are outliers",
                     fontsize=9)
        fig.tight_layout()
        figures.append(Figure(f"batch-{quantity}-{unit}", f"{quantity.capitalize()} per device",
                              f"Each device's {quantity} with its expanded uncertainty, the group's weighted mean "
                              "and the plain mean of the devices; devices flagged by the outlier rule (section 2) "
                              "are red squares.", _svg(fig), series))
    return figures


FIGURES = {"static": [static_figure], "wheel": [wheel_figure], "slider-crank": [slider_crank_figure]}


def figures_for(src: Source, tell: Callable[[str], None] | None = None) -> tuple[list[Figure], list[str]]:
    """The figures this source can show, and the reasons for those it cannot; ``tell`` hears what is being
    done when it takes long (re-running a calibration for its arrays)."""
    from accelrig.report.recompute import add_arrays_from_recording

    figures, missing = [], []
    why_not = add_arrays_from_recording(src, tell)
    if why_not:
        missing.append(why_not)
    makers = FIGURES.get(src.procedure, [])
    for make in makers:
        try:
            figures.append(make(src))
        except LookupError as exc:
            if not why_not:   # else it only restates that the recording's arrays are missing
                missing.append(str(exc))
    if src.procedure == "rotary":
        try:
            figures += rotary_figures(src)
        except LookupError as exc:
            missing.append(str(exc))
    if src.noise:
        figures.append(noise_figure(src))
    return figures, missing
