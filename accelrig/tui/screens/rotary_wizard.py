"""The rotary bench wizard: RotaryProcedure on the contract, plus each axis's sensitivity per step as it
comes; the campaign report (per-step sensitivities, budget, linearity, groups) as tables at the end, saved as
Markdown with s, and the certificate with c.  v ends the session early: the campaign of the steps recorded so far."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rich.markup import escape
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import Screen
from textual.widgets import DataTable, Header, Static

from accelrig.errors import AccelrigError
from accelrig.procedures.rotary.campaign import write_report
from accelrig.procedures.rotary.procedure import RotaryProcedure
from accelrig.result import format_value
from accelrig.tui.screens.dialogs import AsksBeforeClosing, ConfirmScreen, PathScreen, tell
from accelrig.tui.screens.wizard import ProcedureWizard
from accelrig.tui.widgets.keys import KeyFooter
from accelrig.tui.widgets.plot import LinePlot, Series

AXIS_STYLES = {"x": "red", "y": "green", "z": "dodger_blue1"}


class RotaryWizard(ProcedureWizard):
    procedure_class = RotaryProcedure
    ACTION_KEYS = {"space": "capture", "v": "finish"}
    progress_label = "steps"

    def compose_body(self) -> ComposeResult:
        yield LinePlot("sensitivity per step (counts per m/s²)", x_label="step number", id="sensitivity-plot")

    def show_procedure(self, events: list) -> None:
        if not any(e.kind == "captured" for e in events):
            return
        self.query_one("#sensitivity-plot", LinePlot).set_series([
            Series(np.arange(1, len(v) + 1, dtype=float), v, AXIS_STYLES.get(axis, "white"), axis, join=len(v) > 1)
            for axis, v in self.procedure.sensitivities().items()])

    def result_screen(self, result, recording) -> Screen:
        device = self.session.info.to_dict() if self.session is not None and self.session.info else None
        return CampaignScreen(result, device)


def campaign_tables(report: dict) -> list[tuple[str, tuple[str, ...], list[tuple[str, ...]]]]:
    """The campaign's tables for people: (title, columns, rows), units and k in the titles."""
    k = report["coverage_factor"]
    # a value beside its u (or U) is rounded with it, as on every screen (format_value)
    steps = [(str(t["index"]), t["label"], f"{t['sample_rate_hz']['value']:.3f}",
              axis, s["component"], *format_value(s["value"], s["uncertainty"]))
             for t in report["tests"] for axis, s in t["sensitivity"].items()]
    budget, linearity = [], []
    for sensor, axes in report["per_axis"].items():
        for axis, e in axes.items():
            parts = {c["symbol"]: c["uncertainty"] for c in e["budget"]["contributions"]}

            def percent(symbol, parts=parts):
                return f"{100 * parts[symbol]:.3f}" if symbol in parts else "left out"

            # the budget's own combination (Table 2, with the campaign's correlation), not the group result
            # (Table 3, which adds the spread of the results and has its own table below)
            b = e["budget"]
            s_text, u_text = format_value(e["mean_sensitivity"], b["expanded_uncertainty_absolute"])
            budget.append((f"{sensor} {axis}", s_text, percent("u_r"), percent("u_l"),
                           percent("u_ref"), f"{100 * b['combined_standard_uncertainty']:.3f}", u_text))
            line = e["linearity"]
            linearity.append((f"{sensor} {axis}", *((*format_value(line["slope"], line["slope_sd"]),
                                                     f"{line['intercept']:.2f}", f"{line['r_squared']:.6f}",
                                                     str(line["n"])) if line else
                                                    ("not evaluated (see the warnings)", "", "", "", ""))))
    def group(case: str, name: str, e: dict) -> tuple[str, ...]:
        s_text, u_text = format_value(e["mean_sensitivity"], e["expanded_uncertainty"])
        return (case, name, s_text, f"{100 * e['overall_relative_uncertainty']:.3f}", u_text)

    groups = [group("1", f"{sensor} axis {axis}", e)
              for sensor, axes in report["per_axis"].items() for axis, e in axes.items()]
    groups += [group("2", sensor, e) for sensor, e in report["per_sensor"].items()]
    return [
        ("Sensitivity per step (counts per m/s², u at k = 1)",
         ("step", "label", "rate Hz", "axis", "component", "S", "u"), steps),
        (f"Budget per axis (Table 2, one calibration's uncertainty: relative u in %, k = 1, combined with "
         f"correlation {report['correlation']:g}; U at k = {k:g} in counts per m/s²; the group results below "
         "add the spread of the axis's results to it, so their case-1 U is larger)",
         ("axis", "S", "u_r %", "u_l %", "u_ref %", "u_c %", f"U (k={k:g})"), budget),
        ("Linearity q_o = S q_i + b (S in counts per m/s², b in counts)",
         ("axis", "S", "u(S)", "b", "R²", "n"), linearity),
        (f"Group results (Table 3; u in % at k = 1, U at k = {k:g} in counts per m/s²)",
         ("case", "group", "S", "u %", f"U (k={k:g})"), groups),
    ]


class CampaignScreen(AsksBeforeClosing, Screen):
    """The campaign of the steps recorded: per-step sensitivities, budget, linearity, groups; s saves the
    report (Markdown, or YAML by the suffix); c writes the certificate (accelrig.report, as 'accelrig report')."""

    BINDINGS = [Binding("s", "save", "Save report"), Binding("c", "certificate", "Certificate"),
                Binding("escape", "close", "Close")]
    saved_thing = "the campaign report"

    def help_text(self) -> str:
        """What ? shows here (the app's opening text named c as connect, which it is not here)."""
        return ("[b]Rotary bench: the campaign[/b]\n"
                "Read the warnings first: a contribution left out of the budget is said there.  The plot shows each "
                "test's sensitivity per axis (the same axis should agree); the tables give every step's sensitivity "
                "S with its u (k = 1), the uncertainty budget per axis, the linearity line and the group results, "
                "with units and the coverage factor stated.\n"
                "s saves the report (Markdown, or YAML by the file's suffix), c writes the certificate; escape goes "
                "back to the wizard (asking first while the report is not saved).")

    def __init__(self, result, device: dict | None = None):
        super().__init__()
        self.report = result
        self.device = device
        self.saved_path: Path | None = None
        self.certificate_path: Path | None = None

    def compose(self) -> ComposeResult:
        yield Header()
        with VerticalScroll(id="results"):
            yield Static("[b]rotary bench: campaign report[/b]   s saves it (Markdown), c writes the certificate", id="campaign-status")
            if self.report.warnings:
                yield Static("\n".join(f"[yellow]warning:[/] {escape(w)}" for w in self.report.warnings),
                             id="campaign-warnings")
            yield LinePlot("", id="campaign-plot")
            for i, (title, _, _) in enumerate(campaign_tables(self.report.details)):
                yield Static(f"[b]{title}[/b]")
                yield DataTable(id=f"campaign-{i}", show_cursor=False, zebra_stripes=True, classes="quality-table")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.sub_title = "campaign"
        from accelrig.tui.screens.results import result_views

        views = result_views(self.report)
        plot = self.query_one("#campaign-plot", LinePlot)
        if views:
            plot.title, plot.x_label = views[0].title, views[0].x_label
            plot.set_series(views[0].series)
        else:
            plot.display = False
        for i, (_, columns, rows) in enumerate(campaign_tables(self.report.details)):
            table = self.query_one(f"#campaign-{i}", DataTable)
            table.add_columns(*columns)
            for row in rows:
                table.add_row(*row)

    def action_save(self) -> None:
        self.save_flow()

    @work(exclusive=True, group="save-report")
    async def save_flow(self) -> None:
        await self.save_result()

    async def save_result(self) -> bool:
        """Ask where, then write the report (asking before replacing a file); True once it is written."""
        default = str(self.saved_path or Path(self.app.output_dir) / "rotary-campaign.md")
        path = await self.app.push_screen_wait(PathScreen("Save the campaign report to (.md, or .yaml):", default))
        if path is None:
            return False
        target = Path(path).expanduser()
        status = self.query_one("#campaign-status", Static)
        if target.exists() and not await self.app.push_screen_wait(
                ConfirmScreen(f"{target} exists. Overwrite it?", "Overwrite", "Keep it")):
            tell(status, f"not saved: {escape(str(target))} kept as it was")
            return False
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            write_report(self.report, target)
        except (AccelrigError, OSError) as exc:
            tell(status, f"[red]not saved:[/] {escape(str(exc))}")
            return False
        self.saved_path = target
        tell(status, f"[green]report saved to[/] {escape(str(target))}")
        return True

    def action_certificate(self) -> None:
        self.certificate_flow()

    @work(exclusive=True, group="certificate")
    async def certificate_flow(self) -> None:
        from accelrig.tui.screens.certificate import write_certificate_flow

        status = self.query_one("#campaign-status", Static)
        written = await write_certificate_flow(self, self.report, None, self.device, lambda text: tell(status, text))
        if written is not None:
            self.certificate_path = written
