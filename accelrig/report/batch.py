"""A batch report: many devices' calibrations compared in one document (paper 001's many-sensor case).

Every source (profile, saved result, rotary campaign) gives per-device, per-axis
entries with their standard uncertainty:

* from a correction a = C (raw - b): the sensitivity of each sensing axis
  relative to the nominal scale, the norm of row i of S = C^-1 (raw = S a + b,
  misalignment included), with u propagated from C's covariance; and the bias
  b_i (m/s²) with its u;
* from a rotary campaign: each sensor's mean sensitivity per axis (counts per
  m/s²) with the campaign's overall u (paper 001's case 1), one device per sensor.

Entries of the same quantity, axis and unit form a group.  Per group: the
mean, the sd among devices, the weighted mean with its u and the Birge ratio
(above 1: the devices differ by more than their uncertainties).  Each device
is judged by

* E_n = (x - x_ref) / sqrt(U² + U_ref²), U = k u, against the reference device
  when one is named, else against the weighted mean of the *other* devices
  (the device is not compared with itself);
* t = (x - mean of the others) / (sd of the others · sqrt(1 + 1/(n - 1))), the
  device against the prediction interval the other devices give for one more
  of their kind (4 or more devices), with the critical value
  t_crit = t-quantile(1 - 0.05 / (2 n), n - 2): a 5 % chance per group that a
  batch of normal spread flags anyone (Bonferroni over the n devices).

A device is flagged an outlier on an axis when |E_n| > 1 (it disagrees with
the reference beyond the uncertainties, the ISO/IEC 17043 criterion) and
|t| > t_crit (it also stands apart from the batch's own spread: devices of one
type differ genuinely, so E_n alone would flag a good batch whose
uncertainties are small).  With fewer than 4 devices t cannot be evaluated:
against a named reference device |E_n| > 1 alone flags; without one no device
is judged (E_n against the others would flag three sound parts for their
genuine differences), and the document says so.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from accelrig.errors import AccelrigError, DataError
from accelrig.estimation.stats import normalized_error
from accelrig.report.source import Source, load_source

SOURCE_SUFFIXES = (".yaml", ".yml", ".json")
E_N_LIMIT = 1.0
MIN_FOR_T = 4
FAMILY_ALPHA = 0.05       # chance per group that a batch of normal spread flags any device
DEFAULT_K = 2.0


@dataclass
class Entry:
    device: str
    quantity: str      # "sensitivity" or "bias"
    axis: str
    unit: str
    value: float
    u: float           # standard uncertainty, k = 1
    source: int        # index into Batch.sources


@dataclass
class Judged:
    entry: Entry
    reference: float | None
    reference_u: float | None
    e_n: float | None
    t: float | None           # against the others' prediction interval
    outlier: bool


@dataclass
class Group:
    quantity: str
    axis: str
    unit: str
    rows: list[Judged]
    mean: float
    sd: float
    weighted_mean: float
    weighted_mean_u: float
    birge_ratio: float | None
    t_critical: float | None
    rule: str
    judged: bool = True   # False: too few devices and no reference to tell an outlier from the parts' spread


@dataclass
class Batch:
    sources: list[Source]
    labels: list[str]                     # one per source: who it is (identity, or the campaign's name)
    groups: list[Group]
    k: float
    reference: str | None = None
    skipped: list[tuple[str, str]] = field(default_factory=list)   # (file, why it was not read)
    notes: list[str] = field(default_factory=list)

    @property
    def outliers(self) -> list[Judged]:
        return [j for g in self.groups for j in g.rows if j.outlier]

    @property
    def unjudged(self) -> list[Group]:
        """The groups in which no device was judged (fewer than 4 devices and no reference)."""
        return [g for g in self.groups if not g.judged]


def collect_sources(paths: list[str | os.PathLike]) -> tuple[list[Source], list[tuple[str, str]]]:
    """Every source named: files as given (an unreadable one is an error), and each directory's .yaml,
    .yml and .json files; a file in a directory that is not a source is listed as skipped, with why."""
    sources: list[Source] = []
    skipped: list[tuple[str, str]] = []
    for path in map(Path, paths):
        if path.is_dir():
            files = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in SOURCE_SUFFIXES)
            if not files:
                raise DataError(f"{path}: no .yaml, .yml or .json file in this directory",
                                "give a directory of profiles or saved results")
            for file in files:
                try:
                    sources.append(load_source(file))
                except AccelrigError as exc:
                    skipped.append((str(file), exc.message))
        else:
            sources.append(load_source(path))
    if not sources:
        raise DataError("none of the files given is a profile, a saved result or a campaign: "
                        + "; ".join(f"{f}: {why}" for f, why in skipped))
    return sources, skipped


def sensitivity_from_correction(correction: dict) -> tuple[np.ndarray, np.ndarray]:
    """Per axis, |row i of C^-1| (the axis's gain along its sensing direction) and its u from C's covariance
    (first-order propagation with the exact derivative d(C^-1) = -C^-1 dC C^-1)."""
    c = np.asarray(correction["matrix"], dtype=float)
    cov = np.asarray(correction["covariance"], dtype=float)[:9, :9]
    s = np.linalg.inv(c)
    norms = np.linalg.norm(s, axis=1)
    jac = np.zeros((3, 9))
    for m in range(3):
        for n in range(3):
            d_s = -np.outer(s[:, m], s[n, :])          # d(C^-1)/dC[m, n]
            jac[:, 3 * m + n] = np.sum(s * d_s, axis=1) / norms
    u = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", jac, cov, jac), 0, None))
    return norms, u


def source_label(src: Source) -> str:
    if src.is_campaign:
        return str(src.details.get("campaign") or Path(src.path or "campaign").stem)
    return str(src.device.get("identity") or Path(src.path or "device").stem)


def entries_of(src: Source, index: int, label: str) -> list[Entry]:
    if src.is_campaign:
        return [Entry(f"{label}: {sensor}", "sensitivity", axis, "counts/(m/s²)", float(e["mean_sensitivity"]),
                      float(e["overall_uncertainty"]), index)
                for sensor, axes in src.details.get("per_axis", {}).items() for axis, e in axes.items()]
    correction = src.result.get("correction")
    if not correction or "covariance" not in correction:
        return []
    sens, u_sens = sensitivity_from_correction(correction)
    bias, u_bias = correction["bias"], correction["bias_uncertainty"]
    return ([Entry(label, "sensitivity", a, "1", float(sens[i]), float(u_sens[i]), index) for i, a in enumerate("xyz")]
            + [Entry(label, "bias", a, "m/s²", float(bias[i]), float(u_bias[i]), index) for i, a in enumerate("xyz")])


def judge_group(entries: list[Entry], k: float, reference: str | None) -> Group:
    x = np.array([e.value for e in entries])
    u = np.array([e.u for e in entries])
    n = x.size
    positive = u > 0
    weights = np.where(positive, 1.0 / np.where(positive, u, 1.0) ** 2, 0.0)
    if positive.all():
        w_mean = float(np.sum(weights * x) / weights.sum())
        w_u = float(1.0 / math.sqrt(weights.sum()))
        birge = float(math.sqrt(np.sum(weights * (x - w_mean) ** 2) / (n - 1))) if n > 1 else None
    else:
        w_mean, w_u, birge = float(x.mean()), float("nan"), None
    use_t = n >= MIN_FOR_T and x.std() > 0
    t_critical = None
    ref_index = next((i for i, e in enumerate(entries) if e.device == reference), None) if reference else None
    judged = True
    if use_t:
        from scipy.stats import t as student_t

        t_critical = float(student_t.ppf(1 - FAMILY_ALPHA / (2 * n), n - 2))
        rule = f"|E_n| > {E_N_LIMIT:g} and |t| > {t_critical:.2f}"
    elif n < MIN_FOR_T and ref_index is None:
        # E_n against the others' weighted mean would flag sound parts for the genuine spread between
        # parts of one type (their u are far smaller), and a part that is off drags the others' reference
        judged = False
        rule = (f"none: with fewer than {MIN_FOR_T} devices the batch's own spread cannot be measured, so a "
                f"device's E_n against the others cannot tell an outlier from the genuine differences between "
                f"parts; E_n is shown for information. Name a reference device (--reference) or compare "
                f"{MIN_FOR_T} or more")
    elif n < MIN_FOR_T:
        rule = f"|E_n| > {E_N_LIMIT:g} against the reference device (t not evaluated: fewer than {MIN_FOR_T} devices)"
    else:
        rule = f"|E_n| > {E_N_LIMIT:g} (t not evaluated: no spread among the devices)"
    rows = []
    for i, e in enumerate(entries):
        others = [j for j in range(n) if j != i]
        if ref_index is not None:
            ref, ref_u = (None, None) if i == ref_index else (x[ref_index], u[ref_index])
        else:
            weighted = [j for j in others if u[j] > 0]
            if weighted:
                w = 1.0 / u[weighted] ** 2
                ref, ref_u = float(np.sum(w * x[weighted]) / w.sum()), float(1.0 / math.sqrt(w.sum()))
            else:
                ref, ref_u = None, None
        e_n = None
        if ref is not None and (e.u > 0 or ref_u > 0):
            e_n = normalized_error(e.value, k * e.u, ref, k * ref_u)
        t = None
        if use_t:
            spread = float(x[others].std(ddof=1)) * math.sqrt(1 + 1 / (n - 1))
            t = float((e.value - x[others].mean()) / spread) if spread > 0 else math.copysign(math.inf, e.value
                                                                                              - x[others].mean())
        outlier = judged and e_n is not None and abs(e_n) > E_N_LIMIT and (t is None or abs(t) > t_critical)
        rows.append(Judged(e, ref, ref_u, e_n, t, outlier))
    first = entries[0]
    return Group(first.quantity, first.axis, first.unit, rows, float(x.mean()),
                 float(x.std(ddof=1)) if n > 1 else 0.0, w_mean, w_u, birge, t_critical, rule, judged)


def build_batch(sources: list[Source], reference: str | None = None,
                skipped: list[tuple[str, str]] | None = None) -> Batch:
    """Group the sources' entries and judge every device; ``reference`` names the reference device."""
    labels = [source_label(s) for s in sources]
    ks = {float(s.details.get("coverage_factor") or s.result.get("settings", {}).get("coverage_factor") or DEFAULT_K)
          for s in sources}
    k = max(ks)
    notes = []
    if len(ks) > 1:
        notes.append(f"the sources state different coverage factors ({', '.join(f'{v:g}' for v in sorted(ks))}); "
                     f"every U here uses k = {k:g} on each source's standard uncertainty")
    entries, unused = [], []
    for i, (src, label) in enumerate(zip(sources, labels, strict=True)):
        got = entries_of(src, i, label)
        if not got:
            unused.append(f"{label} ({src.path}): no correction with its covariance, nothing to compare")
        entries += got
    seen: dict[str, int] = {}
    for e in entries:
        if e.quantity == "sensitivity" and e.axis == "x":
            seen[e.device] = seen.get(e.device, 0) + 1
    for device, count in seen.items():
        if count > 1:
            notes.append(f"{device} appears {count} times (several calibrations of one device): each is compared "
                         "as a result of its own")
    notes += unused
    if reference is not None and reference not in {e.device for e in entries}:
        raise DataError(f"--reference {reference}: no such device in the batch",
                        "devices: " + ", ".join(sorted({e.device for e in entries})))
    keys = list(dict.fromkeys((e.quantity, e.axis, e.unit) for e in entries))
    groups = [judge_group([e for e in entries if (e.quantity, e.axis, e.unit) == key], k, reference) for key in keys]
    if not groups:
        raise DataError("no source holds a correction or a campaign to compare",
                        "give profiles, saved results with a correction, or rotary campaigns")
    return Batch(sources, labels, groups, k, reference, list(skipped or []), notes)


def load_batch(paths: list[str | os.PathLike], reference: str | None = None) -> Batch:
    sources, skipped = collect_sources(paths)
    return build_batch(sources, reference, skipped)


# ------------------------------------------------------------------ the document


# long hashes and paths (columns 5 and 6 of the devices' table) wrap inside their cells rather than push the
# table off the page; names, chips and dates do not break
BATCH_CSS = ".wrap td{font-size:8pt}.wrap td:nth-child(n+5){word-break:break-all}"
QUANTITY_TITLES = {"sensitivity": "Sensitivity", "bias": "Bias b"}


def _number(value: float | None, digits: int = 3) -> str:
    return "—" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def group_table(group: Group, k: float) -> str:
    from accelrig.report.html import _table, format_value

    rows = []
    for j in group.rows:
        e = j.entry
        value, u = format_value(e.value, e.u)
        ref = "reference" if j.reference is None and j.e_n is None else (
            f"{format_value(j.reference, j.reference_u)[0]} ± {format_value(j.reference, k * j.reference_u)[1]}")
        verdict = "OUTLIER" if j.outlier else "ok" if group.judged else "not judged"
        rows.append([e.device, value, u, format_value(e.value, k * e.u)[1], ref, _number(j.e_n, 2),
                     _number(j.t, 2), verdict])
    head = ["device", "value", "u (k = 1)", f"U (k = {k:g})", f"compared with (U, k = {k:g})", "E_n", "t", "verdict"]
    return _table(head, rows)


def group_summary(group: Group) -> str:
    from accelrig.report.html import format_value

    wm, wu = format_value(group.weighted_mean, group.weighted_mean_u)
    birge = "—" if group.birge_ratio is None else f"{group.birge_ratio:.3g}"
    spread = ("the devices differ by more than their uncertainties" if group.birge_ratio and group.birge_ratio > 1.5
              else "the spread among devices is about what their uncertainties explain")
    return (f"n = {len(group.rows)}; mean {group.mean:.6g}, sd among devices {group.sd:.3g}; weighted mean {wm} "
            f"(u {wu}); Birge ratio {birge} ({spread}). Outlier rule applied: {group.rule}.")


def render_batch_html(batch: Batch, conditions: dict | None = None, figures: list | None = None,
                      issued=None) -> str:
    """One document for the batch: the devices, the comparison rule, per quantity and axis every device with
    U, E_n, t and its verdict, the group statistics, the outliers, every source's warnings, the figures."""
    from datetime import UTC, datetime
    from html import escape

    from accelrig import __version__
    from accelrig.report.html import (
        CONDITION_FIELDS,
        CSS,
        _kv,
        _sentence,
        _table,
        _when,
        approval_block,
        coverage_statement,
        format_value,
        page_css,
    )
    from accelrig.report.wording import as_finding, html_text

    conditions = {key: v for key, v in (conditions or {}).items() if v not in (None, "")}
    issued = issued or datetime.now(UTC)
    k = batch.k
    html = ["<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>Calibration batch report</title>"
            f"<style>{CSS}{BATCH_CSS}{page_css(conditions.get('certificate_number'))}</style></head><body>"
            "<h1>Calibration batch report</h1>"]
    number = conditions.get("certificate_number")
    html.append(f'<p class="note">{("No. " + escape(number) + " · ") if number else ""}issued '
                f"{issued.strftime('%Y-%m-%d %H:%M UTC')} · written with accelrig {escape(__version__)} · "
                f"{len(batch.sources)} sources</p>")
    cond = [(label, conditions.get(key)) for key, label in CONDITION_FIELDS
            if key in conditions and key != "certificate_number"]
    if cond:
        html.append(_kv(cond))

    html.append("<h2>1. Devices</h2>")
    rows = []
    for src, label in zip(batch.sources, batch.labels, strict=True):
        prov = src.provenance
        rows.append([label, str(src.device.get("chip") or "—"), f"{src.procedure} ({src.result.get('method')})",
                     str(_when(prov.get("recording_start") or prov.get("created")) or "—"),
                     str(prov.get("recording_hash") or "—"), str(src.path or "—")])
    html.append('<div class="wrap">' + _table(["device", "chip", "procedure (method)", "date", "recording hash",
                                                  "source"], rows, numeric_from=99) + "</div>")
    if batch.skipped:
        html.append("<h3>Files not read</h3><ul>" + "".join(
            f"<li>{escape(f)}: {escape(why)}</li>" for f, why in batch.skipped) + "</ul>")

    html.append("<h2>2. How the devices are compared</h2>")
    reference = (f"the reference device {escape(batch.reference)}" if batch.reference else
                 "the weighted mean of the other devices (each device is left out of its own reference)")
    html.append(
        "<p>Sensitivity: for a calibration with a correction a = C·(raw − b), the gain of each sensing axis "
        "relative to the nominal scale, |row i of C⁻¹| (misalignment included), with u propagated from C's "
        "covariance; for a rotary campaign, each sensor's mean sensitivity per axis in counts per m/s² with the "
        "campaign's overall u (paper 001, case 1). Bias: b of the correction, in m/s².</p>"
        f"<p>E_n = (x − x_ref) / √(U² + U_ref²) against {reference}; |E_n| ≤ {E_N_LIMIT:g} means agreement "
        "within the expanded uncertainties (ISO/IEC 17043). t = (x − mean of the others) / (sd of the others · "
        "√(1 + 1/(n − 1))) places the device in the prediction interval the other devices of the group give for "
        f"one more of their kind (evaluated with {MIN_FOR_T} or more devices); its critical value t_crit is the "
        f"Student t quantile 1 − {FAMILY_ALPHA:g}/(2n) with n − 2 degrees of freedom, so that a batch of normal "
        f"spread has a {100 * FAMILY_ALPHA:g} % chance per group of flagging any device.</p>"
        f"<p><b>Outlier rule:</b> a device is flagged on an axis when |E_n| &gt; {E_N_LIMIT:g} <i>and</i> "
        "|t| &gt; t_crit: it disagrees with the reference beyond the uncertainties and it also stands apart from "
        "the batch's own spread (sensors of one type differ genuinely, so E_n alone would flag a sound batch "
        f"whose uncertainties are small). Where t is not evaluated, |E_n| &gt; {E_N_LIMIT:g} alone flags. The "
        "Birge ratio √(χ²/(n − 1)) of the weighted mean says whether the devices differ by more than their "
        "uncertainties (above about 1).</p>")
    html.append(f'<p class="note">{escape(coverage_statement(k))}</p>')
    for note in batch.notes:
        html.append(f'<p class="warn">Note: {escape(note)}</p>')

    html.append("<h2>3. Results per quantity and axis</h2>")
    for group in batch.groups:
        unit = "relative to the nominal scale" if group.unit == "1" else group.unit
        html.append(f"<h3>{escape(QUANTITY_TITLES.get(group.quantity, group.quantity))}, axis {escape(group.axis)} "
                    f"({escape(unit)})</h3>")
        html.append(group_table(group, k))
        html.append(f'<p class="note">{escape(group_summary(group))}</p>')

    html.append("<h2>4. Outliers</h2>")
    outliers = batch.outliers
    if outliers:
        html.append("<ul>" + "".join(
            f'<li class="verdict-fail">{html_text(j.entry.device)}: {escape(j.entry.quantity)} {escape(j.entry.axis)} '
            f"= {html_text(format_value(j.entry.value, j.entry.u)[0])} (E_n {_number(j.e_n, 2)}, "
            f"t {_number(j.t, 2)})</li>" for j in outliers) + "</ul>")
    elif not batch.unjudged:
        html.append('<p class="verdict-pass">None: every device agrees with the batch by the rule above.</p>')
    if batch.unjudged:
        html.append(f'<p class="note">Not judged ({len(batch.unjudged)} of {len(batch.groups)} quantities and axes): '
                    f"{escape(batch.unjudged[0].rule)}.</p>")

    html.append("<h2>5. Warnings of the calibrations</h2>")
    warned = [(label, w) for src, label in zip(batch.sources, batch.labels, strict=True)
              for w in src.result.get("warnings") or []]
    html.append("<ul>" + "".join(f'<li class="warn">{html_text(label)}: {html_text(_sentence(as_finding(w)))}</li>'
                                 for label, w in warned)
                + "</ul>" if warned else "<p>None.</p>")

    if figures is not None:
        html.append("<h2>6. Figures</h2>")
        for fig in figures:
            html.append(f"<figure>{fig.svg}<figcaption><b>{escape(fig.title)}.</b> {escape(fig.caption)}"
                        "</figcaption></figure>")
    html.append(approval_block(conditions, "report"))
    html.append('<p class="note">Each device\'s own certificate (accelrig report SOURCE) holds its full results; '
                "this report compares them. It shall not be reproduced except in full.</p></body></html>")
    return "".join(html)


def batch_report_html(batch: Batch, conditions: dict | None = None, figures: bool = True, issued=None) -> str:
    drawn = None
    if figures:
        from accelrig.report.figures import batch_figures

        drawn = batch_figures(batch)
    return render_batch_html(batch, conditions, drawn, issued)
