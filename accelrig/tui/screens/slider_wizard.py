"""The slider-crank wizard: SliderCrankProcedure on the contract, plus the stand's step list and the
frequency response filling in as the steps are taken; the verification screen at the end."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml
from rich.markup import escape
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import VerticalScroll
from textual.screen import Screen
from textual.widgets import Header, Static

from accelrig.errors import AccelrigError
from accelrig.files import atomic_write
from accelrig.procedures.slider_crank.analysis import COVERAGE_FACTOR_LABELS
from accelrig.procedures.slider_crank.procedure import SliderCrankProcedure
from accelrig.profiles import load_profile
from accelrig.profiles.apply import check_compatible, correction_for
from accelrig.report.checks import check_lines
from accelrig.result import format_value, to_plain
from accelrig.tui.screens.dialogs import AsksBeforeClosing, ConfirmScreen, PathScreen, tell
from accelrig.tui.screens.results import result_views
from accelrig.tui.screens.wizard import ProcedureWizard
from accelrig.tui.widgets.keys import KeyFooter
from accelrig.tui.widgets.plot import LinePlot, Series
from accelrig.tui.widgets.table import FittedTable

STEP_COLUMNS = ("step", "Hz", "amplitude", "u", "model", "radius mm", "u mm", "k for U", "flags")
# what a narrow terminal keeps first: each step's radius against the caliper and its flags; the model's
# amplitude goes first (the plot draws it)
STEP_PRIORITY = [STEP_COLUMNS.index(title) for title in
                 ("step", "radius mm", "u mm", "flags", "Hz", "amplitude", "u", "k for U", "model")]


def response_series(frequency, measured, model) -> list[Series]:
    return [Series(frequency, model, "dodger_blue1", "model r ω²"),
            Series(frequency, measured, "yellow", "measured", join=False)]


class SliderCrankWizard(ProcedureWizard):
    procedure_class = SliderCrankProcedure
    ACTION_KEYS = {"space": "capture", "x": "skip", "v": "verify"}
    progress_label = "steps"

    profile_warnings: list[str] = []

    def create_arguments(self, values: dict) -> dict:
        """The calibration under test: the profile's correction, applied to every step first, after the
        same compatibility check as the command line (device, chip, range; the force field overrides)."""
        if not values["profile"]:
            self.profile_warnings = []
            return {}
        profile = load_profile(values["profile"])
        self.profile_warnings = check_compatible(profile, self.device, profile.units, values["force"],
                                                 force_hint="set force to yes to use it anyway")
        return {"correction": correction_for(profile, self.device)}

    def compose_body(self) -> ComposeResult:
        yield Static("", id="slider-steps")
        yield LinePlot("frequency response: first harmonic (m/s²)", x_label="frequency (Hz)", id="fr-plot")

    def show_procedure(self, events: list) -> None:
        procedure = self.procedure
        steps, position = procedure.steps, procedure.position
        skipped = {n for n, _ in procedure.skipped}
        kept = iter(steps)
        cells = [f"[red]✗[/] {procedure.schedule[n]:g}" if n in skipped else f"[green]✓[/] {next(kept).frequency_hz.value:.3g}"
                 for n in range(position)]   # (only a planned schedule has skipped steps)
        cells += [("[b]▶[/] " if i == position else "· ") + f"{speed:g}"
                  for i, speed in enumerate(procedure.schedule or []) if i >= position]
        self.query_one("#slider-steps", Static).update("steps (Hz): " + "  ".join(cells))
        if any(e.kind == "captured" for e in events):
            self.query_one("#fr-plot", LinePlot).set_series(response_series(
                np.array([s.frequency_hz.value for s in steps]), np.array([s.amplitude.value for s in steps]),
                np.array([s.model_amplitude for s in steps])))

    def result_screen(self, result, recording) -> Screen:
        result.warnings = self.profile_warnings + [w for w in result.warnings if w not in self.profile_warnings]
        return VerificationScreen(result)


class VerificationScreen(AsksBeforeClosing, Screen):
    """A slider-crank verification: verdict, radius from the motion, steps, frequency response."""

    BINDINGS = [Binding("s", "save", "Save verification"), Binding("n", "next_plot", "Next plot"),
                Binding("escape", "close", "Close")]
    saved_thing = "the verification"

    def help_text(self) -> str:
        """What ? shows here (the app's opening text named c as connect, which does nothing here)."""
        return ("[b]Slider-crank verification[/b]\n"
                "The verdict at the top says whether the crank radius seen in the sensor's motion agrees with the "
                "caliper within the stated uncertainty, and why.  Read the warnings next, then the checks in "
                "sentences.  The table gives each step (columns a narrow terminal leaves out are named under it); "
                "the lines under it say which coverage factor k is which.  The plot shows the first harmonic "
                "against its clearance band, then the radius per step (n for the next).\n"
                "s saves the verification (YAML, every column); escape goes back to the wizard (asking first while "
                "it is not saved).")

    def __init__(self, verification):
        super().__init__()
        self.verification = verification
        self.saved_path: Path | None = None
        # the results screen's plots of a verification (amplitude against the band, radius per step)
        self.plots = result_views(verification)
        self.plot_index = 0

    def action_save(self) -> None:
        self.save_flow()

    @work(exclusive=True, group="save-verification")
    async def save_flow(self) -> None:
        await self.save_result()

    async def save_result(self) -> bool:
        """The verification as YAML (the fields of --json), where the operator says; True once written."""
        default = str(self.saved_path or Path(self.app.output_dir) / "slider-crank-verification.yaml")
        path = await self.app.push_screen_wait(PathScreen("Save the verification (YAML) to:", default))
        if path is None:
            return False
        target = Path(path).expanduser()
        status = self.query_one("#verification-status", Static)
        if target.exists() and not await self.app.push_screen_wait(
                ConfirmScreen(f"{target} exists. Overwrite it?", "Overwrite", "Keep it")):
            tell(status, f"not saved: {escape(str(target))} kept as it was")
            return False
        text = yaml.safe_dump(to_plain(self.verification.to_json_dict()), sort_keys=False)
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            atomic_write(target, lambda fh: fh.write(text), text=True)
        except (AccelrigError, OSError) as exc:
            tell(status, f"[red]not saved:[/] {escape(str(exc))}")
            return False
        self.saved_path = target
        tell(status, f"[green]verification saved to[/] {escape(str(target))}")
        return True

    def compose(self) -> ComposeResult:
        v, r = self.verification.details, self.verification.parameters["radius"]
        colour = {"holds": "green", "does not hold": "red"}.get(v["verdict"], "yellow")
        yield Header()
        with VerticalScroll(id="results"):
            yield Static(f"[b]slider-crank verification: [{colour}]{v['verdict']}[/][/b]\n{v['verdict_reason']}",
                         id="verdict")
            yield Static("s saves the verification, n shows the next plot", id="verification-status")
            # warnings first, as on the results screen: what to read before trusting the verdict
            yield Static("\n".join(f"[yellow]warning:[/] {escape(w)}" for w in self.verification.warnings)
                         or "[green]no warnings[/]", id="verification-warnings")
            # the checks in sentences (accelrig.report.checks), as on the results screen: a check not made says so
            yield Static("\n".join(f"[b]{what}:[/b] {escape(sentence)}"
                                   for what, sentence in check_lines(self.verification.to_json_dict())),
                         id="verification-checks")
            value_mm, u_mm = format_value(r.value * 1e3, r.uncertainty * 1e3)
            yield Static(f"radius from the motion {value_mm} ± {u_mm} mm "
                         f"(k = 1, chi² {v['radius_chi2']:.3g} for {v['radius_dof']} dof; judged at "
                         f"k = {v.get('radius_k', 2.0):.2f}); caliper "
                         f"{v['crank_radius_m'] * 1e3:g} ± {v['clearance_m'] * 1e3:g} mm"
                         + (f"; motor tops out near {v['rolloff_hz']:.2f} Hz" if v["rolloff_hz"] is not None else ""),
                         id="verification-radius")
            # the columns that fit whole (at 80 columns the table was 3 cells too wide and scrolled sideways)
            yield FittedTable(STEP_PRIORITY, id="steps")
            yield Static("", id="steps-left-out")
            # which k is which (analysis.coverage_factors, the same text as the CLI's and the JSON's)
            yield Static("\n".join(f"[b]{escape(label)}:[/b] {escape(v.get('coverage_factors', {})[key])}"
                                   for key, label in COVERAGE_FACTOR_LABELS.items() if key in v.get("coverage_factors", {})),
                         id="verification-k")
            yield LinePlot("", id="verification-plot")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.sub_title = "verification"
        rows = []
        steps = self.verification.details["steps"]
        for s in steps:
            flags = [name for name, on_ in (("motor-limited", s["motor_limited"]), ("backlash", s["backlash"]),
                                            ("link rings", s["link_ringing"]), ("unsteady", s["speed_unsteady"]),
                                            ("outside", not s["within_clearance"])) if on_]
            # a value beside its u is rounded with it (format_value), as on every screen
            amplitude, amplitude_u = format_value(s["amplitude"]["value"], s["amplitude"]["uncertainty"])
            radius, radius_u = format_value(s["radius_m"]["value"] * 1e3, s["radius_m"]["uncertainty"] * 1e3)
            rows.append([s["label"], f"{s['frequency_hz']['value']:.3f}", amplitude, amplitude_u,
                         f"{s['model_amplitude']:.4g}", radius, radius_u, f"{s.get('radius_k', 2.0):.2f}",
                         " ".join(flags)])
        self.query_one("#steps", FittedTable).show(STEP_COLUMNS, rows, [s["label"] for s in steps])
        self.show_plot()

    def on_fitted_table_left_out(self, message: FittedTable.LeftOut) -> None:
        """Under the steps: the columns this width leaves out, and where they all are."""
        left_out = message.left_out
        note = self.query_one("#steps-left-out", Static)
        note.update(f"[dim]left out at this width: {', '.join(left_out)} (s saves every column)[/]" if left_out
                    else "")
        note.display = bool(left_out)

    def show_plot(self) -> None:
        view = self.plots[self.plot_index % len(self.plots)]
        plot = self.query_one("#verification-plot", LinePlot)
        plot.title = f"{view.title}  ({self.plot_index % len(self.plots) + 1}/{len(self.plots)}, n: next)"
        plot.x_label = view.x_label
        plot.set_series(view.series)

    def action_next_plot(self) -> None:
        self.plot_index += 1
        self.show_plot()
