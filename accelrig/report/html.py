"""The certificate as one self-contained HTML page (inline CSS and SVG, nothing fetched).

Laid out as an ISO/IEC 17025 calibration certificate: the item, the method
and its reference, the conditions, traceability (software, recording hash),
the results with standard (k = 1) and expanded (k, coverage stated)
uncertainties, the budget where the method has one, quality figures and
verdicts, and every warning in full.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from html import escape

from accelrig import __version__
from accelrig.report.checks import check_lines
from accelrig.report.source import METHOD_REFERENCES, Source
from accelrig.result import Estimate, format_value

DEFAULT_K = 2.0
CONDITION_FIELDS = (("customer", "Customer"), ("operator", "Operator"), ("location", "Location"),
                    ("temperature", "Ambient temperature"), ("humidity", "Relative humidity"),
                    ("certificate_number", "Certificate number"))

CSS = """
body{font-family:'DejaVu Sans',Helvetica,Arial,sans-serif;font-size:10pt;color:#111;max-width:190mm;margin:8mm auto}
h1{font-size:16pt;margin:0 0 2mm}h2{font-size:12pt;border-bottom:1px solid #888;margin:6mm 0 2mm;
break-after:avoid}h3{font-size:10.5pt;margin:4mm 0 1mm}
table{border-collapse:collapse;margin:1mm 0 3mm;break-inside:avoid}td,th{border:1px solid #bbb;padding:1px 5px;
text-align:left;vertical-align:top}th{background:#eee}td.n{text-align:right;font-variant-numeric:tabular-nums;
white-space:nowrap}.kv th{width:48mm}.warn{color:#8a3b00}.verdict-fail{color:#a00;font-weight:bold}
.verdict-pass{color:#060;font-weight:bold}.verdict-open{color:#8a3b00;font-weight:bold}figure{margin:2mm 0;break-inside:avoid}figure svg{max-width:100%;height:auto}
figcaption{font-size:9pt;color:#333}.note{font-size:9pt;color:#333}
@page{size:A4;margin:12mm}
"""


def _plain(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return "[" + ", ".join(_plain(v) for v in value) + "]"
    if isinstance(value, dict):
        return "; ".join(f"{k}: {_plain(v)}" for k, v in value.items())
    if value is None:
        return "—"
    return str(value)


def _kv(rows: list[tuple[str, object]]) -> str:
    body = "".join(f"<tr><th>{escape(k)}</th><td>{escape(_plain(v))}</td></tr>" for k, v in rows)
    return f'<table class="kv">{body}</table>'


def _table(head: list[str], rows: list[list[str]], numeric_from: int = 1) -> str:
    h = "".join(f"<th>{escape(c)}</th>" for c in head)
    body = "".join("<tr>" + "".join(
        f'<td{" class=n" if i >= numeric_from else ""}>{escape(c)}</td>' for i, c in enumerate(r)) + "</tr>"
        for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def scalar_estimates(estimates: dict[str, Estimate]) -> list[tuple[str, float, float, str]]:
    """(label, value, u, unit) per scalar, as shown: a vector estimate gives one row per axis, angles in
    degrees (Estimate.for_display), the unit's powers as superscripts."""
    rows = []
    for name, estimate in estimates.items():
        values, uncs, unit = estimate.for_display()
        unit = unit.replace("^2", "²").replace("^3", "³").replace("^4", "⁴")
        if isinstance(values, list):
            labels = [f"{name}[{a}]" for a in ("x", "y", "z")] if len(values) == 3 else [
                f"{name}[{i}]" for i in range(len(values))]
            rows += [(label, v, u, unit) for label, v, u in zip(labels, values, uncs, strict=True)]
        else:
            rows.append((name, values, uncs, unit))
    return rows


def parameter_rows(src: Source, k: float) -> list[list[str]]:
    """One row per scalar parameter (a vector estimate gives one row per axis): name, value, u, U, unit."""
    estimates = {name: Estimate(est["value"], est["uncertainty"], est["unit"])
                 for name, est in src.result["parameters"].items()}
    return [[label, *format_value(v, u), format_value(v, k * u)[1], unit]
            for label, v, u, unit in scalar_estimates(estimates)]


def correction_rows(correction: dict, k: float) -> list[list[str]]:
    rows = []
    for i, (row, urow) in enumerate(zip(correction["matrix"], correction["matrix_uncertainty"], strict=True)):
        for j, (v, u) in enumerate(zip(row, urow, strict=True)):
            value_text, u_text = format_value(v, u)
            rows.append([f"C[{'xyz'[i]}{'xyz'[j]}]", value_text, u_text, format_value(v, k * u)[1], "1"])
    for i, (v, u) in enumerate(zip(correction["bias"], correction["bias_uncertainty"], strict=True)):
        value_text, u_text = format_value(v, u)
        rows.append([f"b[{'xyz'[i]}]", value_text, u_text, format_value(v, k * u)[1], "m/s²"])
    return rows


def coverage_factor(src: Source) -> float:
    return float(src.details.get("coverage_factor") or src.result.get("settings", {}).get("coverage_factor")
                 or DEFAULT_K)


def coverage_statement(k: float, dof: float | None = None) -> str:
    if dof is not None:   # k = t_p(nu_eff) (GUM G.4): the probability is the t's, not the normal's at this k
        return (f"The expanded uncertainty U = k·u is stated with the coverage factor k = {k:.2f}, Student's t "
                f"for the {dof:.0f} effective degrees of freedom of u (Welch-Satterthwaite, GUM G.4), which "
                "corresponds to a coverage probability of approximately 95 %. The standard uncertainty u (k = 1) "
                "was evaluated following the GUM (JCGM 100:2008).")
    return (f"The expanded uncertainty U = k·u is stated with the coverage factor k = {k:g}, which for a normal "
            f"distribution corresponds to a coverage probability of approximately "
            f"{'95' if abs(k - 2) < 1e-9 else f'{100 * math.erf(k / math.sqrt(2)):.1f}'} %. The standard "
            "uncertainty u (k = 1) was evaluated following the GUM (JCGM 100:2008).")


def _budget_html(budget: dict, title: str) -> str:
    unit = "relative" if budget.get("relative") else budget.get("unit", "")
    rows = [[c["name"], c["symbol"], f"{c['uncertainty']:.3g}", f"{c['coefficient']:.3g}", c.get("note", "")]
            for c in budget["contributions"]]
    rows.append(["combined standard uncertainty", "u_c", f"{budget['combined_standard_uncertainty']:.3g}", "", ""])
    rows.append([f"expanded uncertainty (k = {budget['coverage_factor']:g})", "U",
                 f"{budget['expanded_uncertainty']:.3g}", "", ""])
    extra = ""
    if "expanded_uncertainty_absolute" in budget:
        extra = (f'<p class="note">S = {budget["value"]:.4g} {escape(budget.get("unit", ""))}: u_c = '
                 f'{budget["combined_standard_uncertainty_absolute"]:.3g}, U = '
                 f'{budget["expanded_uncertainty_absolute"]:.3g} {escape(budget.get("unit", ""))}; correlation '
                 f'between contributions: {escape(_plain(budget["correlation"]))}</p>')
    return (f"<h3>{escape(title)} ({escape(unit)})</h3>"
            + _table(["source", "symbol", "u", "sensitivity coefficient", "note"], rows, numeric_from=2) + extra)


def budgets_html(src: Source) -> str:
    d = src.details
    parts = []
    for sensor, axes in d.get("per_axis", {}).items():
        for axis, e in axes.items():
            parts.append(_budget_html(e["budget"], f"{sensor} axis {axis}"))
    for component, ref in (d.get("reference") or {}).items():
        if isinstance(ref, dict) and isinstance(ref.get("budget"), dict) and "contributions" in ref["budget"]:
            parts.append(_budget_html(ref["budget"], f"reference acceleration, {component}"))
    return "".join(parts)


def verdicts_html(src: Source) -> str:
    d = src.details
    parts = []
    if "verdict" in d:
        # the verdicts of procedures/slider_crank/analysis.verdict_for: holds, does not hold, inconclusive
        style = {"holds": "pass", "does not hold": "fail"}.get(str(d["verdict"]), "open")
        parts.append(f'<p>Slider-crank verification: <span class="verdict-{style}">'
                     f'{escape(str(d["verdict"]))}</span> — {escape(str(d.get("verdict_reason", "")))}</p>')
    # what the checks found, in the words of the results screen and the text reports
    parts += [f"<p>{escape(what[0].upper() + what[1:])}: {escape(sentence)}.</p>" for what, sentence in check_lines(src.result)]
    en = d.get("normalized_error") or []
    if en:
        rows = [[" / ".join(e["sensors"]), f"{e['E_n']:.3f}", "yes" if e["consistent"] else "NO"] for e in en]
        parts.append("<h3>Normalised error between sensors (|E_n| ≤ 1 is consistent)</h3>"
                     + _table(["sensors", "E_n", "consistent"], rows))
    anova = d.get("anova")
    if anova:
        rows = []
        for name, a in [*((f"{s}: across axes", a) for s, a in anova.get("across_axes", {}).items()),
                        ("across sensors", anova.get("across_sensors"))]:
            if not a:
                continue
            if "not_evaluated" in a:
                rows.append([name, "—", "—", f"not evaluated: {a['not_evaluated']}"])
            else:
                rows.append([name, f"{a['f_statistic']:.3g}", f"{a['p_value']:.3g}",
                             "yes" if a["means_differ"] else "no"])
        parts.append("<h3>ANOVA</h3>" + _table(["groups", "F", "p", "means differ (5 %)"], rows))
    return "".join(parts)


def groups_html(src: Source, k: float) -> str:
    d = src.details
    if "per_sensor" not in d:
        return ""
    rows = []
    for sensor, axes in d["per_axis"].items():
        for axis, e in axes.items():
            rows.append(["1", f"{sensor} axis {axis}", f"{e['mean_sensitivity']:.3f}",
                         f"{e['overall_uncertainty']:.3f}", f"{e['expanded_uncertainty']:.3f}"])
    for sensor, e in d["per_sensor"].items():
        rows.append(["2", sensor, f"{e['mean_sensitivity']:.3f}", f"{e['overall_uncertainty']:.3f}",
                     f"{e['expanded_uncertainty']:.3f}"])
    b = d["batch"]
    rows.append(["3", f"batch ({len(b['sensors'])} sensors)", f"{b['mean_sensitivity']:.3f}",
                 f"{b['overall_uncertainty']:.3f}", f"{b['expanded_uncertainty']:.3f}"])
    tests = []
    for t in d.get("tests", []):
        rate = t["sample_rate_hz"]
        for axis, e in t["sensitivity"].items():
            value_text, u_text = format_value(e["value"], e["uncertainty"])
            rate_text, rate_u = format_value(rate["value"], rate["uncertainty"])
            tests.append([str(t["index"]), t["sensor"], t["label"], f"{rate_text} ± {rate_u}", axis,
                          e["component"], value_text, u_text, format_value(e["value"], k * e["uncertainty"])[1]])
    per_test = ("<h3>Sensitivity per test, counts per m/s²</h3>"
                + _table(["test", "sensor", "label", "sample rate (Hz)", "axis", "reference", "S", "u (k = 1)",
                          f"U (k = {k:g})"], tests, numeric_from=6)) if tests else ""
    return per_test + ("<h3>Group results (paper 001, Table 3), counts per m/s²</h3>"
            + _table(["case", "group", "S", "u (k = 1)", f"U (k = {k:g})"], rows, numeric_from=2))


def render_html(src: Source, conditions: dict | None = None, figures: list | None = None,
                missing_figures: list[str] | None = None, issued: datetime | None = None) -> str:
    """The certificate page.  ``figures`` are ``report.figures.Figure`` objects (None: a certificate without)."""
    conditions = {k: v for k, v in (conditions or {}).items() if v not in (None, "")}
    r, dev, prov = src.result, src.device, src.provenance
    k = coverage_factor(src)
    issued = issued or datetime.now(UTC)
    # the slider-crank judges a calibration made elsewhere; every other procedure determines one
    title = "Verification certificate" if r["procedure"] == "slider-crank" else "Calibration certificate"
    html = [f"<!DOCTYPE html><html lang=en><head><meta charset=utf-8><title>{escape(title)}</title>"
            f"<style>{CSS}</style></head><body>"]
    html.append(f"<h1>{escape(title)}</h1>")
    number = conditions.get("certificate_number")
    html.append(f'<p class="note">{("No. " + escape(number) + " · ") if number else ""}issued '
                f"{issued.strftime('%Y-%m-%d %H:%M UTC')} by accelrig {escape(__version__)}</p>")

    sections = iter(range(1, 100))

    def heading(title: str) -> str:
        """Sections numbered as shown: one a certificate leaves out (no budget, no figures) leaves no gap."""
        return f"<h2>{next(sections)}. {title}</h2>"

    html.append(heading("Item calibrated"))
    if src.is_campaign:
        html.append(_kv([("campaign", src.details.get("campaign")), ("campaign file", src.details.get("source")),
                         ("sensors", ", ".join(src.details.get("batch", {}).get("sensors", [])))]))
    else:
        html.append(_kv([("identity", dev.get("identity")), ("chip", dev.get("chip")),
                         ("range", f"±{dev['range_g']:g} g" if dev.get("range_g") else None),
                         ("nominal scale", f"{dev['scale']:.6g} m/s² per count" if dev.get("scale") else None),
                         ("sample rate", f"{dev['rate']:g} Hz nominal" if dev.get("rate") else None),
                         ("driver / URL", " ".join(str(x) for x in (dev.get("driver"), dev.get("url")) if x)
                          or None)]))

    html.append(heading("Method"))
    html.append(_kv([("procedure", r["procedure"]), ("method", r["method"]), ("model", r["model"]),
                     ("reference", METHOD_REFERENCES.get(r["procedure"], "—")),
                     ("settings", {kk: v for kk, v in (r.get("settings") or {}).items() if not isinstance(v, list)
                                   or len(v) <= 12})]))

    html.append(heading("Conditions"))
    cond_rows = [(label, conditions.get(key)) for key, label in CONDITION_FIELDS
                 if key in conditions and key != "certificate_number"]
    if prov.get("temperature_c") is not None:
        cond_rows.append(("sensor temperature", f"{prov['temperature_c']:g} °C"))
    records = src.details.get("records") or []   # a live campaign: one recording per test
    cond_rows.append(("date of calibration", prov.get("recording_start") or prov.get("created")
                      or (records[0].get("captured") if records else None)))
    html.append(_kv(cond_rows))

    html.append(heading("Traceability and records"))
    html.append(_kv([("software", f"accelrig {prov.get('software_version') or __version__} (calibration), "
                                  f"accelrig {__version__} (this certificate)"),
                     ("recording hash", prov.get("recording_hash")), ("recording", prov.get("recording_source")),
                     ("samples", prov.get("recording_samples")), ("source of this certificate", src.path)]))
    if records:
        html.append("<h3>Recordings of the tests</h3>")
        html.append(_table(["test", "captured", "samples", "recording hash"],
                           [[str(rec.get("test", i + 1)), str(rec.get("captured") or "—"), str(rec.get("samples")),
                             str(rec.get("recording_hash"))] for i, rec in enumerate(records)]))

    html.append(heading("Results"))
    html.append(f'<p class="note">{escape(coverage_statement(k, src.details.get("coverage_dof")))}</p>')
    head = ["quantity", "value", "u (k = 1)", f"U (k = {k:g})", "unit"]
    if r.get("correction"):
        html.append("<h3>Correction: calibrated = C · (raw − b), raw = counts × nominal scale</h3>")
        html.append(_table(head, correction_rows(r["correction"], k)))
    else:
        html.append('<p class="note">No canonical correction: this method does not determine all of C and b, '
                    "and accelrig does not fill them with guesses.</p>")
    html.append("<h3>Method parameters</h3>")
    if r.get("parameter_meaning"):
        html.append(f'<p class="note">{escape(r["parameter_meaning"])}.</p>')
    html.append(_table(head, parameter_rows(src, k)))
    html.append(groups_html(src, k))

    budgets = budgets_html(src)
    if budgets:
        html.append(heading("Uncertainty budget") + budgets)
    html.append(heading("Quality figures and verdicts"))
    html.append(verdicts_html(src))
    quality = {kk: v for kk, v in (r.get("quality") or {}).items() if not isinstance(v, (list, dict))
               or len(str(v)) < 400}
    html.append(_kv(list(quality.items())))

    html.append(heading("Warnings"))
    warnings = r.get("warnings") or []
    html.append("<ul>" + "".join(f'<li class="warn">{escape(w)}</li>' for w in warnings) + "</ul>"
                if warnings else "<p>None.</p>")

    if figures is not None:
        html.append(heading("Figures"))
        for fig in figures:
            html.append(f"<figure>{fig.svg}<figcaption><b>{escape(fig.title)}.</b> {escape(fig.caption)}"
                        "</figcaption></figure>")
        for reason in missing_figures or []:
            html.append(f'<p class="note">Figure not shown: {escape(reason)}.</p>')
    html.append('<p class="note">The results relate only to the item calibrated, under the conditions stated. '
                "This certificate shall not be reproduced except in full.</p>")
    html.append("</body></html>")
    return "".join(html)
