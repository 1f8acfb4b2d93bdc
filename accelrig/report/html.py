"""The certificate as one self-contained HTML page (inline CSS and SVG, nothing fetched).

Laid out as an ISO/IEC 17025 calibration certificate: the item, the method
and its reference, the conditions, traceability (the measurement reference,
software, recording hash), the results with standard (k = 1) and expanded
(k, coverage stated) uncertainties, the budget where the method has one, the
checks and verdicts, every warning worded as a finding, and an appendix with
the settings and fit figures as recorded.  Text meant for the operator at
the rig (options to pass, what to do next) is left out (report.wording), and
no value, unit or part name breaks across lines.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from html import escape

from accelrig import __version__
from accelrig.report.checks import check_lines, gravity_text
from accelrig.report.source import ESTIMATOR_WORDS, METHOD_REFERENCES, Source
from accelrig.report.wording import as_finding, display_unit, html_text
from accelrig.result import Estimate, format_value

DEFAULT_K = 2.0
# approved_by is not a condition: it has its own block, with the signature (approval_block)
CONDITION_FIELDS = (("customer", "Customer"), ("customer_reference", "Customer reference"),
                    ("operator", "Operator"), ("location", "Location"),
                    ("temperature", "Ambient temperature"), ("humidity", "Relative humidity"),
                    ("certificate_number", "Certificate number"))
# facts of the run, not of the item: wall-clock time and solver iterations change from run to run
NO_BREAK_K = "(k\u00a0=\u00a0"   # "U (k = 2)" in a narrow column stays on one line
RUN_FACTS = ("fit_seconds", "time_s", "n_evaluations", "iterations", "rate_fit_iterations")

CSS = """
body{font-family:'DejaVu Sans',Helvetica,Arial,sans-serif;font-size:10pt;color:#111;max-width:190mm;margin:8mm auto}
h1{font-size:16pt;margin:0 0 2mm}h2{font-size:12pt;border-bottom:1px solid #888;margin:6mm 0 2mm;
break-after:avoid}h3{font-size:10.5pt;margin:4mm 0 1mm}
table{border-collapse:collapse;margin:1mm 0 3mm;break-inside:avoid}td,th{border:1px solid #bbb;padding:1px 5px;
text-align:left;vertical-align:top}th{background:#eee}td.n{text-align:right;font-variant-numeric:tabular-nums;
white-space:nowrap}.kv th{width:48mm;white-space:nowrap}.kv td{overflow-wrap:anywhere}.warn{color:#8a3b00}.verdict-fail{color:#a00;font-weight:bold}
.verdict-pass{color:#060;font-weight:bold}.verdict-open{color:#8a3b00;font-weight:bold}figure{margin:2mm 0;break-inside:avoid}figure svg{max-width:100%;height:auto}
figcaption{font-size:9pt;color:#333}.note{font-size:9pt;color:#333}
body{hyphens:manual}.nb{white-space:nowrap}
@page{size:A4;margin:12mm 12mm 16mm}
.sign td{height:9mm;min-width:60mm}
"""


def page_css(number: str | None) -> str:
    """Each printed page names its document and says which page of how many (ISO/IEC 17025 7.8.2.1),
    in the page's bottom margin, which Chromium fills from CSS @page margin boxes."""
    label = f"No. {number} · " if number else ""
    # a CSS string inside <style>: backslash, quote and line ends escaped as CSS wants them, and < too,
    # so a number holding "</style>" cannot end the style element (the number is free text)
    label = "".join(c if c not in '\\"\n\r<' else f"\\{ord(c):x} " for c in label)
    return ("@page{@bottom-left{content:\"" + label + "Page \" counter(page) \" of \" counter(pages);"
            "font-size:8pt;color:#555}}")


def approval_block(conditions: dict, what: str) -> str:
    """Who authorises the document (named by --approved-by, else a blank to fill in), with lines to sign."""
    name = conditions.get("approved_by")
    return (f"<h3>Authorisation</h3><p class=\"note\">This {what} is issued under the authority of the person "
            "named below.</p><table class=\"kv sign\"><tr><th>Approved by</th><td>"
            + (html_text(name) if name else "") + "</td></tr><tr><th>Signature</th><td></td></tr>"
            "<tr><th>Date</th><td></td></tr></table>")


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
    body = "".join(f"<tr><th>{html_text(k)}</th><td>{html_text(_plain(v))}</td></tr>" for k, v in rows)
    return f'<table class="kv">{body}</table>'


def _table(head: list[str], rows: list[list[str]], numeric_from: int = 1) -> str:
    h = "".join(f"<th>{html_text(c.replace('(k = ', NO_BREAK_K))}</th>" for c in head)
    body = "".join("<tr>" + "".join(
        f'<td{" class=n" if i >= numeric_from else ""}>{html_text(c)}</td>' for i, c in enumerate(r)) + "</tr>"
        for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def scalar_estimates(estimates: dict[str, Estimate]) -> list[tuple[str, float, float, str]]:
    """(label, value, u, unit) per scalar, as shown: a vector estimate gives one row per axis, angles in
    degrees (Estimate.for_display), the unit's powers as superscripts."""
    rows = []
    for name, estimate in estimates.items():
        values, uncs, unit = estimate.for_display()
        unit = display_unit(unit)
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


def u_text(u: float) -> str:
    """An uncertainty printed on its own, by the one rule (format_value: two significant digits)."""
    return format_value(u, u)[1]


def _budget_html(budget: dict, title: str, symbol: str = "S") -> str:
    """One budget; ``symbol`` names the quantity its absolute u_c and U belong to (S, a_ref)."""
    # a relative budget in %, as the campaign's Markdown report (UncertaintyBudget.markdown) prints it
    scale, unit = (100.0, "relative, %") if budget.get("relative") else (1.0, display_unit(budget.get("unit", "")))
    rows = [[c["name"], c["symbol"], u_text(scale * c["uncertainty"]), f"{c['coefficient']:.3g}", c.get("note", "")]
            for c in budget["contributions"]]
    rows.append(["combined standard uncertainty", "u_c", u_text(scale * budget["combined_standard_uncertainty"]),
                 "", ""])
    rows.append([f"expanded uncertainty (k = {budget['coverage_factor']:g})", "U",
                 u_text(scale * budget["expanded_uncertainty"]), "", ""])
    extra = ""
    if "expanded_uncertainty_absolute" in budget:
        # S, u_c and U as the results print them: S to the place of u_c's two digits, U by the same rule
        unit_abs = display_unit(budget.get("unit", ""))
        value_text, u_c_text = format_value(budget["value"], budget["combined_standard_uncertainty_absolute"])
        extra = (f'<p class="note">{html_text(symbol)} = {html_text(value_text)} {html_text(unit_abs)}: u_c = {html_text(u_c_text)}, '
                 f'U = {html_text(u_text(budget["expanded_uncertainty_absolute"]))} {html_text(unit_abs)}; '
                 f'correlation between contributions: {html_text(_plain(budget["correlation"]))}</p>')
    return (f"<h3>{html_text(title)} ({html_text(unit)})</h3>"
            + _table(["source", "symbol", "u", "sensitivity coefficient", "note"], rows, numeric_from=2) + extra)


def budgets_html(src: Source) -> str:
    d = src.details
    parts = []
    for sensor, axes in d.get("per_axis", {}).items():
        for axis, e in axes.items():
            parts.append(_budget_html(e["budget"], f"{sensor} axis {axis}"))
    for component, ref in (d.get("reference") or {}).items():
        if isinstance(ref, dict) and isinstance(ref.get("budget"), dict) and "contributions" in ref["budget"]:
            parts.append(_budget_html(ref["budget"], f"reference acceleration, {component}", "a_ref"))
    return "".join(parts)


def verdicts_html(src: Source) -> str:
    d = src.details
    parts = []
    if "verdict" in d:
        # the verdicts of procedures/slider_crank/analysis.verdict_for: holds, does not hold, inconclusive
        style = {"holds": "pass", "does not hold": "fail"}.get(str(d["verdict"]), "open")
        parts.append(f'<p>Slider-crank verification: <span class="verdict-{style}">'
                     f'{html_text(str(d["verdict"]))}</span> — {html_text(as_finding(d.get("verdict_reason", "")))}</p>')
    # what the checks found, in the words of the results screen and the text reports, without the advice
    parts += [f"<p>{html_text(what[0].upper() + what[1:])}: {html_text(_sentence(as_finding(sentence)))}</p>"
              for what, sentence in check_lines(src.result)]
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


def _sentence(text: str) -> str:
    """``text`` ending in a full stop (not capitalised: it may start with a symbol, u(g) or gain_x)."""
    text = str(text).strip()
    return text if not text or text.endswith((".", "?", "!")) else text + "."


def _group_row(case: str, group: str, e: dict) -> list[str]:
    value_text, u_text_ = format_value(e["mean_sensitivity"], e["overall_uncertainty"])
    return [case, group, value_text, u_text_, format_value(e["mean_sensitivity"], e["expanded_uncertainty"])[1]]


def groups_html(src: Source, k: float) -> str:
    d = src.details
    if "per_sensor" not in d:
        return ""
    rows = [_group_row("1", f"{sensor} axis {axis}", e) for sensor, axes in d["per_axis"].items()
            for axis, e in axes.items()]
    rows += [_group_row("2", f"{sensor} (mean of its axes)", e) for sensor, e in d["per_sensor"].items()]
    b = d["batch"]
    rows.append(_group_row("3", f"batch ({len(b['sensors'])} sensors)", b))
    tests = []
    for t in d.get("tests", []):
        rate = t["sample_rate_hz"]
        for axis, e in t["sensitivity"].items():
            value_text, u_text_ = format_value(e["value"], e["uncertainty"])
            rate_text, rate_u = format_value(rate["value"], rate["uncertainty"])
            tests.append([str(t["index"]), t["sensor"], t["label"], f"{rate_text}\u00a0±\u00a0{rate_u}", axis,
                          e["component"], value_text, u_text_, format_value(e["value"], k * e["uncertainty"])[1]])
    per_test = ("<h3>Sensitivity per test, counts per m/s²</h3>"
                + _table(["test", "sensor", "label", "sample rate (Hz)", "axis", "reference", "S", "u (k = 1)",
                          f"U (k = {k:g})"], tests, numeric_from=6)) if tests else ""
    return per_test + ("<h3>Group results (paper 001, Table 3), counts per m/s²</h3>"
            + _table(["case", "group", "S", "u (k = 1)", f"U (k = {k:g})"], rows, numeric_from=2))


def _when(stamp) -> str | None:
    """An ISO 8601 time as a person reads it (2026-01-15 08:00 UTC); anything else as it is."""
    if not stamp:
        return None
    try:
        when = datetime.fromisoformat(str(stamp).replace("Z", "+00:00"))
    except ValueError:
        return str(stamp)
    if when.tzinfo is None:
        return when.strftime("%Y-%m-%d %H:%M")
    return when.astimezone(UTC).strftime("%Y-%m-%d %H:%M UTC")


def measurement_reference(src: Source) -> str:
    """What the results are traced to: the local gravity for the gravity methods (its value, u and where it
    came from), the bench's encoder for the rotary method, the caliper for the slider-crank."""
    settings = src.result.get("settings") or {}
    rig = src.provenance.get("rig") or settings.get("rig") or {}
    parts = []
    if src.procedure in ("static", "wheel") and settings.get("g") is not None:
        if settings.get("g_u") is not None:
            parts.append(f"local gravity {gravity_text(settings)} (standard uncertainty): "
                         f"{as_finding(settings.get('g_source') or 'as given')}")
        else:   # a result of a version that kept no u(g)
            parts.append(f"local gravity g = {settings['g']:g} m/s², as given (no uncertainty recorded with it)")
    if src.procedure == "wheel" and isinstance(rig, dict) and rig.get("radius"):
        parts.append(f"wheel radius {rig['radius']:g} m ({'measured, as given' if rig.get('radius_given') else 'fitted'})")
    if src.procedure == "rotary":
        parts.append("the bench's encoder angle (the reference acceleration and its u, u_ref in the budget)")
    if src.procedure == "slider-crank":
        radius, clearance = settings.get("crank_radius_m"), settings.get("clearance_m")
        stated = (f" ({1e3 * radius:.3f} mm, clearance ± {1e3 * clearance:.3f} mm)"
                  if radius is not None and clearance is not None else "")
        parts.append(f"the crank radius measured with a caliper and the stated clearance{stated}")
    return "; ".join(parts) or "—"


def appendix_rows(src: Source) -> tuple[list, list]:
    """The settings and the fit's figures as the calibration recorded them, for the record: lists of up to
    12 items, no run facts (RUN_FACTS), nothing the certificate already says in sentences."""
    def shown(key, value):
        return key not in RUN_FACTS and value not in (None, "", [], {}) and (
            not isinstance(value, (list, dict)) or len(str(value)) < 400)

    def worded(value):
        return as_finding(value) if isinstance(value, str) else value

    settings = [(key, worded(v)) for key, v in (src.result.get("settings") or {}).items()
                if shown(key, v) and key not in ("g", "g_u", "g_source")]
    said = ("uncertainty_source", "uncertainty")   # in the checks' sentences
    quality = [(key, worded(v)) for key, v in (src.result.get("quality") or {}).items()
               if shown(key, v) and key not in said]
    return settings, quality


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
            f"<style>{CSS}{page_css(conditions.get('certificate_number'))}</style></head><body>"]
    html.append(f"<h1>{escape(title)}</h1>")
    number = conditions.get("certificate_number")
    html.append(f'<p class="note">{("No. " + html_text(number) + " · ") if number else ""}issued '
                f"{html_text(issued.strftime('%Y-%m-%d %H:%M UTC'))} · written with accelrig {html_text(__version__)}</p>")

    sections = iter(range(1, 100))

    def heading(title: str) -> str:
        """Sections numbered as shown: one a certificate leaves out (no budget, no figures) leaves no gap."""
        return f"<h2>{next(sections)}. {title}</h2>"

    verifies = r["procedure"] == "slider-crank"
    html.append(heading("Item verified" if verifies else "Item calibrated"))
    device_rows = [(label, value) for label, value in (
        ("Identity", dev.get("identity") or "not recorded"), ("Chip", dev.get("chip")),
        ("Range", f"±{dev['range_g']:g} g" if dev.get("range_g") else None),
        ("Nominal scale", f"{dev['scale']:.6g} m/s² per count" if dev.get("scale") else None),
        ("Sample rate", f"{dev['rate']:g} Hz nominal" if dev.get("rate") else None),
        ("Connection", " ".join(str(x) for x in (dev.get("driver"), dev.get("url")) if x) or None))
        if value is not None]
    if src.is_campaign:
        # a campaign from a file names the file; one recorded live in the TUI has none, but has its device
        records = src.details.get("records") or []
        source = src.details.get("source") or (
            f"none: recorded live, one recording per test ({len(records)}, under Recordings of the tests)"
            if records else "not recorded")
        html.append(_kv([("Campaign", src.details.get("campaign")), ("Campaign file", source),
                         ("Sensors", ", ".join(src.details.get("batch", {}).get("sensors", []))),
                         *(device_rows if dev.get("identity") else [])]))
    else:
        html.append(_kv(device_rows))

    html.append(heading("Method"))
    words = ESTIMATOR_WORDS.get((r["procedure"], r["method"]))
    html.append(_kv([("Procedure", r["procedure"]),
                     ("Estimator", f"{r['method']} ({words})" if words else r["method"]), ("Model", r["model"]),
                     ("Reference document", METHOD_REFERENCES.get(r["procedure"], "—"))]))
    html.append('<p class="note">The settings the calibration used are listed in the appendix.</p>')

    html.append(heading("Conditions"))
    cond_rows = [(label, conditions.get(key)) for key, label in CONDITION_FIELDS
                 if key in conditions and key != "certificate_number"]
    if prov.get("temperature_c") is not None:
        cond_rows.append(("Sensor temperature", f"{prov['temperature_c']:g} °C"))
    records = src.details.get("records") or []   # a live campaign: one recording per test
    cond_rows.append((f"Date of {'verification' if verifies else 'calibration'}", _when(prov.get("recording_start") or prov.get("created")
                                                   or (records[0].get("captured") if records else None))
                      or "not stated in the source"))
    html.append(_kv(cond_rows))

    html.append(heading("Traceability and records"))
    html.append(_kv([(label, value) for label, value in (
        ("Measurement reference", measurement_reference(src)),
        ("Software", f"accelrig {prov.get('software_version') or __version__} (calibration), "
                     f"accelrig {__version__} (this certificate)"),
        ("Recording hash", prov.get("recording_hash")), ("Recording", prov.get("recording_source")),
        ("Samples", prov.get("recording_samples")), ("Source of this certificate", src.path))
        if value is not None]))
    if records:
        html.append("<h3>Recordings of the tests</h3>")
        html.append(_table(["test", "captured", "samples", "recording hash"],
                           [[str(rec.get("test", i + 1)), str(_when(rec.get("captured")) or "—"),
                             str(rec.get("samples")), str(rec.get("recording_hash"))] for i, rec in enumerate(records)]))

    html.append(heading("Results"))
    html.append(f'<p class="note">{html_text(coverage_statement(k, src.details.get("coverage_dof")))}</p>')
    # k as the coverage statement gives it: a Student's t to two decimals, a chosen k as given
    k_text = f"{k:.2f}" if src.details.get("coverage_dof") is not None else f"{k:g}"
    head = ["quantity", "value", "u (k = 1)", f"U (k = {k_text})", "unit"]
    if r.get("correction"):
        html.append("<h3>Correction: calibrated = C · (raw − b), raw = counts × nominal scale</h3>")
        html.append(_table(head, correction_rows(r["correction"], k)))
    else:
        html.append('<p class="note">No correction matrix C and bias b are stated: this method does not determine '
                    "all of them.</p>")
    html.append("<h3>Method parameters</h3>")
    if r.get("parameter_meaning"):
        html.append(f'<p class="note">{html_text(_sentence(r["parameter_meaning"]))}</p>')
    html.append(_table(head, parameter_rows(src, k)))
    html.append(groups_html(src, k))
    if "verdict" not in src.details:
        html.append('<p class="note">No statement of conformity to a specification is made.</p>')

    budgets = budgets_html(src)
    if budgets:
        html.append(heading("Uncertainty budget") + budgets)
    html.append(heading("Checks and verdicts"))
    html.append(verdicts_html(src) or '<p class="note">The method records no check beyond its uncertainty budget '
                "and the warnings below.</p>")

    html.append(heading("Warnings"))
    warnings = r.get("warnings") or []
    html.append("<ul>" + "".join(f'<li class="warn">{html_text(_sentence(as_finding(w)))}</li>' for w in warnings)
                + "</ul>" if warnings else "<p>None.</p>")

    if figures is not None:
        html.append(heading("Figures"))
        for fig in figures:
            html.append(f"<figure>{fig.svg}<figcaption><b>{html_text(fig.title)}.</b> {html_text(fig.caption)}"
                        "</figcaption></figure>")
        for reason in missing_figures or []:
            html.append(f'<p class="note">Figure not shown: {html_text(as_finding(reason))}.</p>')

    html.append(approval_block(conditions, "verification certificate" if verifies else "certificate"))

    settings, quality = appendix_rows(src)
    html.append("<h2>Appendix: settings and fit figures as recorded</h2>")
    html.append('<p class="note">For the record and for repeating the calibration; the results above do not '
                "need them to be read.</p>")
    if settings:
        html.append("<h3>Settings</h3>" + _kv(settings))
    if quality:
        html.append("<h3>Fit figures</h3>" + _kv(quality))
    html.append('<p class="note">The results relate only to the item calibrated, under the conditions stated. '
                "This certificate shall not be reproduced except in full.</p>")
    html.append("</body></html>")
    return "".join(html)
