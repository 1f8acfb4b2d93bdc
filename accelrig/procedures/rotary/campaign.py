"""Rotary bench campaigns (paper 001 sections 2.6 and 3): many tests, one report.

A campaign YAML lists tests (sensors, axis orientations, frequencies,
amplitudes, repeats) and the bench's reference inputs.  The report holds:

* per test: rate, reference, sensitivities (see bench.py);
* per sensor axis: repeatability u_rep (pooled relative sd over repeated
  setups), linearity (q_o = S q_i + b over amplitudes: sigma_S, R^2,
  residuals; u_l = sigma_S / S), reference u_ref, the combined budget of
  Table 2 with a configurable correlation between contributions (1 by
  default, as the paper) and expanded k = 2;
* group results (Table 3): case 1 per axis of each sensor (calibration
  u_c combined with the sd of its results), case 2 per sensor (mean over axes,
  case-1 uncertainty combined with the sd among axes), case 3 the batch
  (combined with the sd among sensors);
* one-way ANOVA across the axes of each sensor and across sensors;
* E_n between sensors (case 2 values), with the shared reference removed;
* Bland-Altman of the reference accelerometer against the encoder where a
  ``ref`` channel is present.

YAML (paths relative to the YAML file; per-test keys override the defaults)::

    name: LSM6DSR batch
    nominal_rate: 1660          # Hz
    radius: 0.170               # m
    radius_uncertainty: 0.0005  # m
    geometry_uncertainty: 0.000346   # relative (paper: 0.06 % / sqrt 3)
    encoder_resolution_deg: 0.01
    ref_radius: 0.145           # m, reference accelerometer
    rate_method: fit            # or scan
    components: [tangential, centripetal]   # add dc to use the radial DC part
    correlation: 1.0            # between u_rep, u_l, u_ref
    coverage_factor: 2
    units: counts               # of the MEMS files (default: what each file declares, else counts)
    tests:
      - {sensor: S1, mems: s1_xy_5hz_a.csv, encoder: s1_xy_5hz_a_enc.csv,
         tangential: x, radial: y, frequency: 5}
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from accelrig.errors import AccelrigError, CalibrationError, DataError
from accelrig.estimation.gum import Contribution, UncertaintyBudget
from accelrig.estimation.stats import linear_regression, normalized_error, one_way_anova
from accelrig.files import atomic_write
from accelrig.procedures.rotary.bench import (
    COMPONENTS,
    RATE_METHODS,
    RotarySetup,
    RotaryTest,
    analyse_test,
    read_encoder_csv,
)
from accelrig.recording import load_recording, loss_warning
from accelrig.result import CalibrationResult, Estimate, format_value, to_plain
from accelrig.safe_yaml import load_yaml_file
from accelrig.spec import Field, ListOf, Number, Object, OneOf, String, check, optional

# A linearity line q_o = S q_i + b through reference amplitudes that barely differ is an extrapolation:
# its slope sd grows as 1 / (spread of q_i), and three repeats at one setting (spread ~0.1 %) gave a
# +-60 % "linearity" term.  The regression is run only when the largest reference amplitude is at least
# this many times the smallest (the paper's plan spans about 5 : 1); otherwise the term is left out, warned.
LINEARITY_MIN_SPAN = 1.5

# Keys a test may take from the campaign's top level (per-test values override them).
DEFAULT_FIELDS = {
    "radius": optional(Number(exclusive_minimum=0.0, description="m")),
    "radius_uncertainty": optional(Number(minimum=0.0, description="m")),
    "geometry_uncertainty": optional(Number(minimum=0.0, description="relative")),
    "encoder_resolution_deg": optional(Number(exclusive_minimum=0.0)),
    "ref_radius": optional(Number(minimum=0.0, description="m")),
    "nominal_rate": optional(Number(exclusive_minimum=0.0, description="Hz")),
    "rate_method": optional(String(enum=RATE_METHODS)),
    "units": optional(String()),
    "frequency": optional(Number(exclusive_minimum=0.0, description="Hz")),
}
NAME = OneOf((String(min_length=1), Number()), expected="a name")
TEST = Object({
    **DEFAULT_FIELDS,
    "sensor": optional(NAME),
    "label": optional(NAME),
    "mems": Field(String(min_length=1, description="MEMS recording, relative to the campaign file")),
    "encoder": optional(String(min_length=1)),
    "tangential": Field(String(min_length=1)),
    "radial": Field(String(min_length=1)),
})
CAMPAIGN = Object({
    **DEFAULT_FIELDS,
    "name": optional(NAME),
    "components": optional(ListOf(String(enum=COMPONENTS))),
    "correlation": optional(Number(minimum=-1.0, maximum=1.0)),
    "coverage_factor": optional(Number(exclusive_minimum=0.0)),
    "amplitude_tolerance": optional(Number(exclusive_minimum=0.0)),
    "tests": Field(ListOf(TEST)),
}, description="a rotary bench campaign")


@dataclass
class Observation:
    """One sensitivity from one test: what the campaign statistics work on."""

    test: int
    sensor: str
    axis: str
    component: str
    frequency: float
    reference: float  # q_i, m/s^2
    output: float  # q_o, counts
    sensitivity: float
    reference_uncertainty: float  # relative


@dataclass
class CampaignTest:
    index: int
    sensor: str
    label: str
    mems: str
    encoder: str | None
    options: dict
    setup: RotarySetup


@dataclass
class Campaign:
    name: str
    tests: list[CampaignTest]
    components: tuple[str, ...] = ("tangential", "centripetal")
    correlation: float = 1.0
    coverage_factor: float = 2.0
    amplitude_tolerance: float = 0.02
    source: str = ""


def _setup_from(values: dict) -> RotarySetup:
    kwargs = {key: float(values[key]) for key in ("radius", "radius_uncertainty", "geometry_uncertainty", "ref_radius")
              if key in values}
    if "encoder_resolution_deg" in values:
        kwargs["encoder_resolution"] = float(np.deg2rad(values["encoder_resolution_deg"]))
    return RotarySetup(**kwargs)


def load_campaign(path: str | os.PathLike) -> Campaign:
    """Read and validate a campaign YAML (``CAMPAIGN``); every error names the field."""
    path = Path(path)
    data = load_yaml_file(path, DataError, "a campaign YAML")
    check(CAMPAIGN, data, DataError, where=f"{path}: ")
    if not data["tests"] or not data.get("components", COMPONENTS):
        raise DataError(f"{path}: 'tests' and 'components' must not be empty")
    defaults = {key: data[key] for key in DEFAULT_FIELDS if key in data}
    out = []
    for i, entry in enumerate(data["tests"]):
        merged = {**defaults, **entry}
        if "nominal_rate" not in merged:
            raise DataError(f"{path}: tests[{i}]: missing 'nominal_rate'", "give it in the test or at the top")
        options = {
            "tangential": merged["tangential"],
            "radial": merged["radial"],
            "nominal_rate": float(merged["nominal_rate"]),
            "frequency": float(merged["frequency"]) if "frequency" in merged else None,
            "rate_method": merged.get("rate_method", "fit"),
            "units": merged.get("units"),   # None: what the file declares, else counts
        }
        encoder = merged.get("encoder")
        out.append(CampaignTest(
            index=i + 1,   # numbered from 1 in reports and certificates, as the TUI numbers its steps
            sensor=str(merged.get("sensor", "sensor")),
            label=str(merged.get("label", Path(merged["mems"]).stem)),
            mems=str(path.parent / merged["mems"]),
            encoder=str(path.parent / encoder) if encoder else None,
            options=options,
            setup=_setup_from(merged),
        ))
    return Campaign(
        name=str(data.get("name", path.stem)), tests=out,
        components=tuple(data.get("components", ("tangential", "centripetal"))),
        correlation=float(data.get("correlation", 1.0)), coverage_factor=float(data.get("coverage_factor", 2.0)),
        amplitude_tolerance=float(data.get("amplitude_tolerance", 0.02)), source=str(path),
    )


def run_test(test: CampaignTest) -> RotaryTest:
    o = test.options
    try:
        mems = load_recording(test.mems, units=o["units"], rate=o["nominal_rate"], default_units="counts")
        encoder = read_encoder_csv(test.encoder) if test.encoder else None
        result = analyse_test(mems, encoder, o["tangential"], o["radial"], o["nominal_rate"],
                              o["frequency"], o["rate_method"], test.setup)
        if (loss := loss_warning(mems)) is not None:   # heavy link loss: in the test's (and the report's) warnings
            result.warnings.append(loss)
            result.quality["link_loss"] = loss         # for the command to say on stderr
        return result
    except AccelrigError as exc:
        # name the test: in a campaign of 50 files "not found on the tangential axis" alone is no help
        raise type(exc)(f"test {test.index} ({test.label}): {exc.message}", exc.hint) from None


def observations_of(index: int, sensor: str, result: RotaryTest, components) -> list[Observation]:
    out = []
    items = list(result.sensitivity.values())
    if "dc" in components:
        items.append(result.dc_sensitivity)
    for s in items:
        if s.component not in components:
            continue
        out.append(Observation(index, sensor, s.axis, s.component, result.frequency.value,
                               s.reference_amplitude, s.output_amplitude, s.value, s.reference_uncertainty))
    return out


def _setups(obs: list[Observation], tolerance: float) -> list[list[Observation]]:
    """Group repeats: same sensor, axis, component, frequency (1 %), reference amplitude within ``tolerance``."""
    groups: list[list[Observation]] = []
    for o in obs:
        for g in groups:
            first = g[0]
            if ((first.sensor, first.axis, first.component) == (o.sensor, o.axis, o.component)
                    and abs(o.frequency / first.frequency - 1) < 0.01
                    and abs(o.reference / first.reference - 1) < tolerance):
                g.append(o)
                break
        else:
            groups.append([o])
    return groups


def analyse_campaign(campaign: Campaign, results: list[RotaryTest]) -> CalibrationResult:
    """Statistics of a campaign whose tests were analysed into ``results`` (same order).

    The sensitivity of each sensor axis (case 1, k = 1) is a parameter; the
    tests, budgets, groups and comparisons are the ``details`` tables.  No
    canonical correction: gains without offsets are not one.
    """
    k = campaign.coverage_factor
    warnings: list[str] = []
    obs: list[Observation] = []
    for test, res in zip(campaign.tests, results, strict=True):
        obs += observations_of(test.index, test.sensor, res, campaign.components)
        warnings += [f"test {test.index} ({test.label}): {w}" for w in res.warnings]
    sensors = sorted({o.sensor for o in obs})
    setups = _setups(obs, campaign.amplitude_tolerance)

    per_axis: dict[str, dict[str, dict]] = {}
    for sensor in sensors:
        per_axis[sensor] = {}
        for axis in sorted({o.axis for o in obs if o.sensor == sensor}):
            mine = [o for o in obs if o.sensor == sensor and o.axis == axis]
            values = np.array([o.sensitivity for o in mine])
            mean = float(values.mean())
            entry: dict = {"n": len(mine), "mean_sensitivity": mean,
                           "components": sorted({o.component for o in mine})}
            # repeatability: pooled relative sd over setups that were repeated
            reps = [g for g in setups if g[0].sensor == sensor and g[0].axis == axis and len(g) >= 2]
            contributions = []
            if reps:
                dof = sum(len(g) - 1 for g in reps)
                pooled = sum((len(g) - 1) * np.var([o.sensitivity for o in g], ddof=1) / np.mean(
                    [o.sensitivity for o in g]) ** 2 for g in reps) / dof
                u_rep = float(np.sqrt(pooled))
                entry["repeatability"] = {"relative_sd": u_rep, "setups": len(reps), "dof": int(dof)}
                contributions.append(Contribution("repeatability", "u_r", u_rep))
            else:
                entry["repeatability"] = None
                warnings.append(f"{sensor} axis {axis}: no repeated setup, repeatability not evaluated "
                                "(left out of the budget)")
            # linearity over amplitudes
            q_i = np.array([o.reference for o in mine])
            q_o = np.array([o.output for o in mine])
            span = float(np.max(np.abs(q_i)) / np.min(np.abs(q_i)))
            try:
                if span < LINEARITY_MIN_SPAN:
                    raise CalibrationError(
                        f"the reference amplitudes span only {span:.3f} : 1 and a regression needs at least "
                        f"{LINEARITY_MIN_SPAN:g} : 1; record steps at several amplitudes")
                line = linear_regression(q_i, q_o)
                u_l = line.slope_sd / abs(line.slope)
                entry["linearity"] = {**line.to_dict(), "relative_slope_sd": float(u_l),
                                      "reference": q_i.tolist(), "output": q_o.tolist()}
                contributions.append(Contribution("linearity", "u_l", float(u_l)))
            except CalibrationError as exc:
                entry["linearity"] = None
                warnings.append(f"{sensor} axis {axis}: linearity not evaluated ({exc.message}); left out of the budget")
            u_ref = float(np.sqrt(np.mean([o.reference_uncertainty**2 for o in mine])))
            contributions.append(Contribution("reference", "u_ref", u_ref))
            budget = UncertaintyBudget(contributions, correlation=campaign.correlation, k=k, relative=True,
                                       value=mean, unit="counts/(m/s^2)")
            sd_rel = float(values.std(ddof=1) / mean) if values.size > 1 else 0.0
            case1 = float(np.hypot(budget.combined, sd_rel))
            entry.update({
                "reference_relative_uncertainty": u_ref,
                "budget": budget.to_dict(),
                "budget_markdown": budget.markdown(),
                "relative_sd_of_results": sd_rel,
                "overall_relative_uncertainty": case1,
                "overall_uncertainty": case1 * mean,
                "expanded_uncertainty": k * case1 * mean,
            })
            per_axis[sensor][axis] = entry

    per_sensor: dict[str, dict] = {}
    for sensor, axes in per_axis.items():
        means = np.array([a["mean_sensitivity"] for a in axes.values()])
        u1 = np.array([a["overall_relative_uncertainty"] for a in axes.values()])
        mean = float(means.mean())
        sd_rel = float(means.std(ddof=1) / mean) if means.size > 1 else 0.0
        u_rel = float(np.hypot(np.sqrt(np.mean(u1**2)), sd_rel))
        u_ref = float(np.sqrt(np.mean([a["reference_relative_uncertainty"] ** 2 for a in axes.values()])))
        per_sensor[sensor] = {"mean_sensitivity": mean, "axes": sorted(axes), "relative_sd_among_axes": sd_rel,
                              "overall_relative_uncertainty": u_rel, "overall_uncertainty": u_rel * mean,
                              "expanded_uncertainty": k * u_rel * mean, "reference_relative_uncertainty": u_ref}
    s_means = np.array([s["mean_sensitivity"] for s in per_sensor.values()])
    u2 = np.array([s["overall_relative_uncertainty"] for s in per_sensor.values()])
    b_mean = float(s_means.mean())
    b_sd = float(s_means.std(ddof=1) / b_mean) if s_means.size > 1 else 0.0
    b_u = float(np.hypot(np.sqrt(np.mean(u2**2)), b_sd))
    batch = {"mean_sensitivity": b_mean, "sensors": sensors, "relative_sd_among_sensors": b_sd,
             "overall_relative_uncertainty": b_u, "overall_uncertainty": b_u * b_mean,
             "expanded_uncertainty": k * b_u * b_mean}

    anova = {"across_axes": {}, "across_sensors": None}
    for sensor in sensors:
        groups = {a: [o.sensitivity for o in obs if o.sensor == sensor and o.axis == a] for a in per_axis[sensor]}
        try:
            across = one_way_anova(groups)
        except CalibrationError as exc:
            anova["across_axes"][sensor] = {"not_evaluated": exc.message}
            continue
        anova["across_axes"][sensor] = across.to_dict()
        if not across.equal_means():
            # the paper's case 2 is one value for any axis: with axes that differ, it is not any one axis's
            # sensitivity, which a reader of the group table could take it for
            per = ", ".join(f"{axis} {format_value(m, per_axis[sensor][axis]['overall_uncertainty'])[0]}"
                            for axis, m in across.group_means.items())
            warnings.append(
                f"{sensor}: its axes' sensitivities differ (one-way ANOVA F = {across.f_statistic:.3g}, "
                f"p = {across.p_value:.2g}; {per}): the case 2 value "
                f"{format_value(per_sensor[sensor]['mean_sensitivity'], per_sensor[sensor]['overall_uncertainty'])[0]}"
                " is their mean, its u widened by their spread, and stands for the sensor as a whole; each axis's "
                "own sensitivity is its case 1 value")
    try:
        anova["across_sensors"] = one_way_anova(
            {s: [o.sensitivity for o in obs if o.sensor == s] for s in sensors}).to_dict()
    except CalibrationError as exc:
        anova["across_sensors"] = {"not_evaluated": exc.message}

    en = []
    for i, a in enumerate(sensors):
        for b in sensors[i + 1:]:
            pa, pb = per_sensor[a], per_sensor[b]
            # both sensors were referred to the same bench: the reference part of their
            # uncertainties is common and cannot explain a difference between them
            shared = k * np.sqrt(pa["reference_relative_uncertainty"] * pb["reference_relative_uncertainty"]
                                 * pa["mean_sensitivity"] * pb["mean_sensitivity"])
            value = normalized_error(pa["mean_sensitivity"], pa["expanded_uncertainty"],
                                     pb["mean_sensitivity"], pb["expanded_uncertainty"], shared)
            en.append({"sensors": [a, b], "E_n": value, "consistent": bool(abs(value) <= 1.0)})

    bland = [
        {"test": t.index, "label": t.label, **r.bland_altman}
        for t, r in zip(campaign.tests, results, strict=True) if r.bland_altman is not None
    ]
    parameters = {f"sensitivity_{sensor}_{axis}": Estimate(e["mean_sensitivity"], e["overall_uncertainty"],
                                                           "counts/(m/s^2)")
                  for sensor, axes in per_axis.items() for axis, e in axes.items()}
    return CalibrationResult(
        procedure="rotary",
        method="campaign",
        model="q_o = S q_i + b",
        correction=None,
        parameters=parameters,
        parameter_meaning=("sensitivity_SENSOR_AXIS: the mean over the campaign's tests, counts per m/s^2, with "
                           "the overall uncertainty of the tests' spread and the reference"),
        quality={"n_tests": len(results)},
        settings={"components": list(campaign.components), "correlation": campaign.correlation,
                  "coverage_factor": k},
        warnings=warnings,
        details={
            "campaign": campaign.name,
            "source": campaign.source,
            "components": list(campaign.components),
            "correlation": campaign.correlation,
            "coverage_factor": k,
            "tests": [{"index": t.index, "sensor": t.sensor, "label": t.label, **r.to_json_dict()}
                      for t, r in zip(campaign.tests, results, strict=True)],
            "per_axis": per_axis,
            "per_sensor": per_sensor,
            "batch": batch,
            "anova": anova,
            "normalized_error": en,
            "bland_altman": bland,
        },
    )


def run_campaign(path: str | os.PathLike, on_test=None) -> CalibrationResult:
    """Load, analyse every test, and return the report.  ``on_test(test, result)`` sees each test."""
    campaign = load_campaign(path)
    results = []
    for test in campaign.tests:
        result = run_test(test)
        results.append(result)
        if on_test is not None:
            on_test(test, result)
    return analyse_campaign(campaign, results)


# ------------------------------------------------------------------ report


def report_markdown(result: CalibrationResult) -> str:
    report = result.details
    k = report["coverage_factor"]

    def s_u_U(e: dict) -> str:
        """S | u (%) | U of a group (paper 001, Table 3), rounded by the one rule (format_value): S and U as
        the certificate prints them."""
        u_percent = 100 * e["overall_relative_uncertainty"]
        return (f"{format_value(e['mean_sensitivity'], e['overall_uncertainty'])[0]} | "
                f"{format_value(u_percent, u_percent)[1]} | "
                f"{format_value(e['mean_sensitivity'], e['expanded_uncertainty'])[1]}")

    lines = [f"# Rotary bench campaign: {report['campaign']}", ""]
    lines += ["## Tests", "", "| # | sensor | label | rate (Hz) | u (Hz) | axis | component | S (counts per m/s^2) | u |",
              "|---|---|---|---|---|---|---|---|---|"]
    for t in report["tests"]:
        rate, rate_u = format_value(t["sample_rate_hz"]["value"], t["sample_rate_hz"]["uncertainty"])
        for axis, s in t["sensitivity"].items():
            s_text, u_text = format_value(s["value"], s["uncertainty"])
            lines.append(f"| {t['index']} | {t['sensor']} | {t['label']} | {rate} | {rate_u} | {axis} | "
                         f"{s['component']} | {s_text} | {u_text} |")
    lines += ["", "## Budget per sensor axis (Table 2)", ""]
    for sensor, axes in report["per_axis"].items():
        for axis, e in axes.items():
            s_text = format_value(e["mean_sensitivity"], e["overall_uncertainty"])[0]
            lines += [f"### {sensor} axis {axis}: S = {s_text} counts per m/s^2", "", e["budget_markdown"], ""]
            if e["linearity"]:
                lin = e["linearity"]
                slope, slope_u = format_value(lin["slope"], lin["slope_sd"])
                lines.append(f"Linearity: S = {slope} +- {slope_u}, b = "
                             f"{lin['intercept']:.2f} counts, R^2 = {lin['r_squared']:.6f}, n = {lin['n']}")
                lines.append("")
    lines += ["## Group results (Table 3)", "", "| case | group | S (counts per m/s^2) | u (%) | "
              f"U, k = {k:g} (counts per m/s^2) |", "|---|---|---|---|---|"]
    for sensor, axes in report["per_axis"].items():
        for axis, e in axes.items():
            lines.append(f"| 1 | {sensor} axis {axis} | {s_u_U(e)} |")
    for sensor, e in report["per_sensor"].items():
        lines.append(f"| 2 | {sensor} (mean of its axes) | {s_u_U(e)} |")
    b = report["batch"]
    lines.append(f"| 3 | batch ({len(b['sensors'])} sensor{'' if len(b['sensors']) == 1 else 's'}) | {s_u_U(b)} |")
    lines += ["", "## ANOVA", "", "| groups | F | p | means differ (5 %) |", "|---|---|---|---|"]
    for sensor, a in report["anova"]["across_axes"].items():
        lines.append(_anova_row(f"{sensor}: across axes", a))
    lines.append(_anova_row("across sensors", report["anova"]["across_sensors"]))
    if report["normalized_error"]:
        lines += ["", "## Normalised error between sensors", "", "| sensors | E_n | consistent |", "|---|---|---|"]
        for e in report["normalized_error"]:
            lines.append(f"| {' / '.join(e['sensors'])} | {e['E_n']:.3f} | {'yes' if e['consistent'] else 'NO'} |")
    if report["bland_altman"]:
        lines += ["", "## Bland-Altman: reference accelerometer minus encoder (m/s^2)", "",
                  "| test | bias | sd | limits of agreement | n |", "|---|---|---|---|---|"]
        for e in report["bland_altman"]:
            lines.append(f"| {e['test']} {e['label']} | {e['bias']:.4f} | {e['sd']:.4f} | "
                         f"{e['lower_limit_of_agreement']:.4f} .. {e['upper_limit_of_agreement']:.4f} | {e['n']} |")
    if result.warnings:
        lines += ["", "## Warnings", ""] + [f"- {w}" for w in result.warnings]
    return "\n".join(lines) + "\n"


def _anova_row(name: str, a: dict) -> str:
    if "not_evaluated" in a:
        return f"| {name} | - | - | not evaluated: {a['not_evaluated']} |"
    return f"| {name} | {a['f_statistic']:.3g} | {a['p_value']:.3g} | {'yes' if a['means_differ'] else 'no'} |"


def write_report(result: CalibrationResult, path: str | os.PathLike, overwrite: bool = True, inputs=()) -> None:
    """Write the report as YAML (.yaml/.yml: the JSON convention's fields) or Markdown (.md), atomically
    (``overwrite`` and ``inputs`` as in files.atomic_write)."""
    suffix = Path(path).suffix.lower()
    if suffix in (".yaml", ".yml"):
        text = yaml.safe_dump(to_plain(result.to_json_dict()), sort_keys=False)
    elif suffix in (".md", ".markdown"):
        text = report_markdown(result)
    else:
        raise DataError(f"{path}: the report format follows the suffix", "use .yaml, .yml or .md")
    atomic_write(path, lambda fh: fh.write(text), text=True, overwrite=overwrite, inputs=inputs)
