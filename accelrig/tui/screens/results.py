"""Results of any procedure: parameters with uncertainty, quality, plots; save and flash.

Everything shown comes from the CalibrationResult; the profile is made and
saved by accelrig.profiles, the flash planned and rendered by accelrig.profiles.flash.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rich.markup import escape
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical, VerticalScroll
from textual.screen import Screen
from textual.widgets import DataTable, Header, Static

from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.session import Session
from accelrig.errors import AccelrigError
from accelrig.profiles.flash import flash_url_profile, format_plan, plan_flash, url_reapplying
from accelrig.recording import Recording
from accelrig.report.html import format_value, scalar_estimates
from accelrig.result import CalibrationResult
from accelrig.tui.screens.certificate import file_stem, write_certificate_flow
from accelrig.tui.screens.dialogs import (
    DIALOG_TEXT_WIDTH,
    AsksBeforeClosing,
    ChoiceScreen,
    ConfirmScreen,
    PathScreen,
    tell,
)
from accelrig.tui.widgets.keys import KeyFooter
from accelrig.tui.widgets.plot import LinePlot, Series

SERIES_STYLES = ("red", "green", "dodger_blue1", "yellow", "magenta", "cyan")


# Units of the arrays the procedures return (plotted with their name); an array not listed is drawn
# with its name alone.
ARRAY_UNITS = {
    "residuals": "m/s²", "pose_means": "m/s²", "pose_references": "m/s²", "pose_residuals": "m/s²",
    "pose_times": "s", "speed_samples": "rad/s", "speed_fit": "rad/s", "speed_residuals": "rad/s",
    "amplitude": "m/s²", "amplitude_uncertainty": "m/s²", "model_amplitude": "m/s²", "model_lower": "m/s²",
    "model_upper": "m/s²", "radius_m": "m", "radius_uncertainty_m": "m",
    "filtered_tangential": "m/s²", "filtered_radial": "m/s²",
}
# x arrays, by name (NAME_x of any array; t and *_time in s; frequency in Hz)
X_NAMES = ("t", "frequency", "frequency_hz")


def x_label(name: str) -> str:
    if name == "t" or name.endswith("_time"):
        return "time (s)"
    if name.startswith("frequency"):
        return "frequency (Hz)"
    return name


def plot_series(name: str, arrays: dict) -> tuple[str, list[Series]] | None:
    """How to draw ``arrays[name]``: (x axis label, series), against its x array when the result gives one.

    Convention used by the procedures' ``arrays``: ``NAME`` (1-D or n x k)
    and optionally ``NAME_x``, or a time (``t``, ``*_time``) or frequency array of the
    same length as the x axis; otherwise entries are drawn against their number.
    """
    y = np.asarray(arrays[name], dtype=float)
    if y.ndim == 0 or y.size < 2 or y.ndim > 2:
        return None
    n = y.shape[0]
    x = None
    x_name = "pose number" if name.startswith("pose_") else "entry number"
    candidates = [f"{name}_x", *X_NAMES, *(key for key in arrays if key.endswith("_time"))]
    for candidate in candidates:
        if candidate != name and candidate in arrays and np.asarray(arrays[candidate]).shape == (n,):
            x, x_name = np.asarray(arrays[candidate], dtype=float), x_label(candidate)
            break
    if x is None:
        x = np.arange(n, dtype=float) + 1.0
    columns = y.reshape(n, -1)
    labels = ("x", "y", "z") if columns.shape[1] == 3 else tuple(str(i) for i in range(columns.shape[1]))
    series = [
        Series(x, columns[:, k], SERIES_STYLES[k % len(SERIES_STYLES)], labels[k] if columns.shape[1] > 1 else "")
        for k in range(columns.shape[1])
    ]
    return x_name, series


@dataclass
class PlotView:
    """One plot of the results screen: the title names the quantity with its unit, x_label the x axis's."""

    title: str
    x_label: str
    series: list[Series]


def _points(x, y, style: str, label: str = "") -> Series:
    return Series(np.asarray(x, dtype=float), np.asarray(y, dtype=float), style, label, join=False)


def _axes(x, columns: np.ndarray, join: bool = False) -> list[Series]:
    return [Series(np.asarray(x, dtype=float), columns[:, k], SERIES_STYLES[k], "xyz"[k], join=join)
            for k in range(columns.shape[1])]


def static_views(src) -> list[PlotView]:
    from accelrig.report.figures import static_series

    s = static_series(src)
    x, x_name = (s["pose_time_s"], "time (s), middle of each pose") if "pose_time_s" in s else (s["pose"], "pose")
    magnitude = [_points(x, s["after"], "green", "after")]
    if "before" in s:
        magnitude.insert(0, _points(x, s["before"], "grey50", "before"))
    views = [PlotView("|a| − g per pose (m/s²): after should sit near 0", x_name, magnitude)]
    if "residuals" in s:
        views.append(PlotView("fit residual per pose (m/s²): no pose should stand out", x_name,
                              _axes(x, s["residuals"])))
    return views


def wheel_views(src) -> list[PlotView]:
    from accelrig.report.figures import wheel_series

    s = wheel_series(src)
    views = [
        PlotView("wheel speed (rad/s): half turns on the fitted law", "time (s)",
                 [_points(s["speed_time"], s["speed_samples"], "yellow", "half turns"),
                  Series(s["speed_time"], s["speed_fit"], "dodger_blue1", "fitted law")]),
        PlotView("speed residual (rad/s): no trend", "time (s)",
                 [_points(s["speed_time"], s["speed_residuals"], "yellow")]),
        PlotView("acceleration residual (m/s²): flat noise, no drift", "time (s)", _axes(s["t"], s["residuals"])),
    ]
    if "angle_deg" in s:
        views.append(PlotView("acceleration residual (m/s²) against the wheel angle: no wave", "angle (degrees)",
                              _axes(s["angle_deg"], s["residuals"])))
    freq, spectrum = s["spectrum_frequency"][1:], s["spectrum"][1:]
    views.append(PlotView("residual spectrum, log10 of (m/s²)/√Hz: white, no peak", "frequency (Hz)",
                          _axes(freq, np.log10(np.maximum(spectrum, 1e-30)), join=True)))
    return views


def slider_crank_views(src) -> list[PlotView]:
    from accelrig.report.figures import slider_crank_series

    s = slider_crank_series(src)
    f = s["frequency_hz"]
    order = np.argsort(f)
    band = [Series(f[order], s[k][order], "grey50", label) for k, label in
            (("model_lower", "clearance band"), ("model_upper", ""))]
    views = [PlotView("first-harmonic amplitude (m/s²): should lie inside the band", "crank frequency (Hz)",
                      [*band, Series(f[order], s["model_amplitude"][order], "dodger_blue1", "model"),
                       _points(f, s["amplitude"], "yellow", "measured")])]
    r0, clearance = src.details.get("crank_radius_m"), src.details.get("clearance_m") or 0.0
    radius = [_points(f, 1e3 * s["radius_m"], "yellow", "from the motion")]
    if r0 is not None:
        radius = [Series(f[order], np.full(f.size, 1e3 * (r0 + sign * clearance)), "grey50",
                         "caliper ± clearance" if sign > 0 else "") for sign in (1, -1)] + radius
    views.append(PlotView("crank radius per step (mm): should lie inside the clearance band", "crank frequency (Hz)", radius))
    return views


def rotary_views(src) -> list[PlotView]:
    from accelrig.report.figures import rotary_sensitivity_series

    groups, s = rotary_sensitivity_series(src)
    series = []
    for k, group in enumerate(dict.fromkeys(groups)):
        sel = [i for i, g in enumerate(groups) if g == group]
        series.append(_points(s["test"][sel], s["sensitivity"][sel], SERIES_STYLES[k % len(SERIES_STYLES)],
                              group))
    return [PlotView("sensitivity per test (counts per m/s²): the same axis should agree", "test number", series)]


VIEWS = {"static": static_views, "wheel": wheel_views, "slider-crank": slider_crank_views, "rotary": rotary_views}


def result_views(result: CalibrationResult, recording: Recording | None = None) -> list[PlotView]:
    """The plots of a result with physical axes: the arrays the certificate's figures draw (accelrig.report
    computes them), else each array against its time or frequency (``plot_series``)."""
    make = VIEWS.get(result.procedure)
    if make is not None:
        from accelrig.report import from_result

        try:
            return make(from_result(result, recording))
        except LookupError:
            pass   # this result does not carry the figure's arrays: draw what it has
    views = []
    for name in plottable(result.arrays):
        x_name, series = plot_series(name, result.arrays)
        unit = ARRAY_UNITS.get(name)
        views.append(PlotView(name + (f" ({unit})" if unit else ""), x_name, series))
    return views


def plottable(arrays: dict) -> list[str]:
    names = []
    for name in arrays:
        if name.endswith(("_x", "_time")) or name in X_NAMES:
            continue
        if plot_series(name, arrays) is not None:
            names.append(name)
    return names


def cell_text(value) -> str:
    if isinstance(value, (float, np.floating)):
        return f"{value:.4g}"
    if isinstance(value, (list, tuple)) and all(isinstance(v, (int, float)) for v in value):
        return ", ".join(f"{v:.3g}" for v in value)
    return str(value)


def can_flash(session: Session | None) -> bool:
    """A device is connected and can store a calibration (Driver.can_flash)."""
    if session is None or session.info is None or session.driver is None:
        return False
    return session.driver.can_flash


def correction_rows(result: CalibrationResult) -> list[tuple[str, ...]]:
    """The canonical correction a = C (raw - b) per axis: C's row and b, each followed by a row of their u
    (k = 1), rounded together (GUM 7.2.6); value and u in one cell would not fit 80 columns."""
    c = result.correction
    if c is None:
        return []
    rows = []
    for i, axis in enumerate("xyz"):
        cells = [format_value(float(c.matrix[i, j]), float(c.matrix_uncertainty[i, j])) for j in range(3)]
        cells.append(format_value(float(c.bias[i]), float(c.bias_uncertainty[i])))
        rows.append((axis, *(value for value, _ in cells)))
        rows.append(("  u", *(u for _, u in cells)))
    return rows


def default_profile_name(result: CalibrationResult, session: Session | None) -> str:
    identity = session.info.identity if session is not None and session.info is not None else "device"
    return f"{file_stem(identity)}-{result.procedure}.yaml"


class ResultsScreen(AsksBeforeClosing, Screen):
    saved_thing = "the profile"
    BINDINGS = [
        Binding("s", "save", "Save profile"),
        Binding("f", "flash", "Flash"),
        Binding("n", "next_plot", "Next plot"),
        Binding("c", "certificate", "Certificate"),
        Binding("escape", "close", "Close"),
    ]

    def __init__(self, result: CalibrationResult, recording: Recording | None, session: Session | None):
        super().__init__()
        self.result = result
        self.recording = recording
        self.session = session
        self.plots = result_views(result, recording)
        self.plot_index = 0
        self.certificate_path: Path | None = None
        self.profile = None
        self.saved_path: Path | None = None
        self.flashing = False   # a flash is under way (its steps must not be started twice)

    def compose(self) -> ComposeResult:
        r = self.result
        yield Header()
        with VerticalScroll(id="results"):
            yield Static(f"[b]{r.procedure}[/b]  method {r.method}  model {r.model}", id="results-title")
            yield Static("s saves the profile" + (", f flashes it to the device" if can_flash(self.session) else "")
                         + ", n shows the next plot, c writes the certificate", id="results-status")
            # warnings first: what the operator must read before saving (the quality figures follow the plot)
            yield Static(self.warnings_text(), id="results-warnings")
            # then the numbers, in view on opening: the sentences below them have grown long enough to push
            # the last parameter row below the fold of a 120x40 terminal
            if r.correction is not None:
                yield Static("[b]Correction[/b] a = C (raw − b), what the profile applies; under each axis its u "
                            "(k = 1), values rounded to it")
                yield DataTable(id="correction", show_cursor=False, zebra_stripes=True)
            yield Static("[b]Parameters[/b] as the method estimates them, u at k = 1"
                         + (f": {escape(r.parameter_meaning)}" if r.parameter_meaning else ""), id="parameters-title")
            yield DataTable(id="parameters", show_cursor=False, zebra_stripes=True)
            # what the checks found and what u holds, in sentences (the raw figures come last)
            yield Static(self.checks_text(), id="results-checks")
            with Vertical(id="plot-box"):
                yield LinePlot("", id="result-plot")
            if self.result.details.get("poses"):
                yield Static("[b]Poses[/b] found in the recording and what became of each, as the text report lists "
                            "them: the nearest face and how far off it, and the |g| residual in m/s² (or why the "
                            "pose was not used)")
                yield DataTable(id="poses", show_cursor=False, zebra_stripes=True)
            yield Static(self.quality_text(), id="quality")
            for key, _ in self.quality_tables():
                yield Static(f"[b]{key}[/b]")
                yield DataTable(id=f"quality-{key}", show_cursor=False, classes="quality-table")
        yield KeyFooter()

    def on_mount(self) -> None:
        self.sub_title = "results"
        if self.result.correction is not None:
            table = self.query_one("#correction", DataTable)
            table.add_columns("axis", "C ·x", "C ·y", "C ·z", "b m/s²")
            for row in correction_rows(self.result):
                table.add_row(*row)
        table = self.query_one("#parameters", DataTable)
        table.add_columns("parameter", "value", "u (k=1)", "unit")
        for label, value, uncertainty, unit in scalar_estimates(self.result.parameters):
            # escaped: a str cell is read as markup, and "gain[x]" lost its "[x]" (three rows named "gain")
            table.add_row(*(escape(cell) for cell in (label, *format_value(value, uncertainty), unit)))
        if self.result.details.get("poses"):
            table = self.query_one("#poses", DataTable)
            table.add_columns("pose", "from s", "to s", "n", "face", "off °", "fate", "|g| resid.")
            for r in self.result.details["poses"]:
                fit = f"{r['magnitude_residual']:+.4f}" if "magnitude_residual" in r else str(r.get("reason", ""))
                table.add_row(str(r["index"]), f"{r['start']:.2f}", f"{r['stop']:.2f}", str(r["n"]), str(r["face"]),
                              f"{r['angle_deg']:.1f}", escape(str(r["fate"])), escape(fit))
        for key, rows in self.quality_tables():
            table = self.query_one(f"#quality-{key}", DataTable)
            columns = list(rows[0])
            table.add_columns(*columns)
            for row in rows:
                table.add_row(*[escape(cell_text(row.get(c))) for c in columns])
        self.show_plot()
        try:
            from accelrig.profiles import profile_from_result
        except ModuleNotFoundError:
            self.set_status("[red]profiles are not part of this installation:[/] the result cannot be saved")
            return
        device = self.device_facts()
        try:
            self.profile = profile_from_result(self.result, self.recording, device=device)
        except AccelrigError as exc:
            self.set_status(f"[red]no profile can be made:[/] {exc}")

    def help_text(self) -> str:
        """What ? shows on the results: how to read them, then this screen's keys (listed by the help)."""
        return (f"[b]Results of the {escape(self.result.procedure)} calibration[/b] (method "
                f"{escape(self.result.method)}, model {escape(self.result.model)})\n"
                "Read the warnings at the top first: each says what the data showed that the model does not hold, "
                "how large, and whether u already includes it.\n"
                "Correction: what the profile applies to raw readings, a = C (raw - b).  Parameters: what the method "
                "estimated.  Every u is a standard uncertainty (k = 1); a coverage factor, where one is stated, "
                "is named next to it.\n"
                "Below the tables, the checks say what u holds, whether the model fits, the noise found and "
                "the local gravity the gains are scaled to.  Parameters name their form: a static gain and offset "
                "correct the reading, the wheel's are the sensor's own; the correction is the same form for all.\n"
                "The figure below the tables shows the fit against the data (n for the next one); every quality "
                "figure follows at the end, as the profile keeps it.\n"
                "s saves the device profile to the store, c writes a certificate, f (when the device can take "
                "it) flashes the profile to it; escape goes back to the wizard, where the captured data are kept (asking "
                "first, while the profile is not saved, whether to save it, discard it or stay).")

    def quality_text(self) -> str:
        """Scalar and short numeric quality figures; tables (lists of rows) are shown separately."""
        parts = []
        for key, value in self.result.quality.items():
            if isinstance(value, bool) or value is None:
                parts.append(f"{key} {value}")
            elif isinstance(value, (int, np.integer)):
                parts.append(f"{key} {int(value)}")   # a count is an integer ("n_samples 1.118e+04" before)
            elif isinstance(value, (float, np.floating)):
                # NaN is how a figure that could not be computed is kept (a p-value with no degrees of freedom)
                parts.append(f"{key} not computed" if np.isnan(value) else f"{key} {value:.4g}")
            elif isinstance(value, str):
                parts.append(f"{key} {value}")
            else:
                try:
                    numbers = np.asarray(value, dtype=float).ravel()
                except (TypeError, ValueError):
                    continue  # a table or a nested structure
                if numbers.size <= 12:
                    parts.append(f"{key} [" + ", ".join(f"{v:.3g}" for v in numbers) + "]")
        return ("[b]All quality figures[/b] (as the profile and --json keep them): "
                + (escape("   ".join(parts)) if parts else "none reported"))

    def checks_text(self) -> str:
        """What the checks found and what u holds, one sentence each (accelrig.report.checks)."""
        from accelrig.report.checks import check_lines

        lines = check_lines(self.result.to_json_dict())
        return "\n".join(f"[b]{what}:[/b] {escape(sentence)}" for what, sentence in lines) or "no checks reported"

    def warnings_text(self) -> str:
        """The result's warnings, one per line (or that there are none)."""
        if not self.result.warnings:
            return "[green]no warnings[/]"
        return "\n".join(f"[yellow]warning:[/] {escape(warning)}" for warning in self.result.warnings)

    def quality_tables(self) -> list[tuple[str, list[dict]]]:
        """Quality entries that are lists of rows (e.g. per face): shown as tables."""
        return [(key, value) for key, value in self.result.quality.items()
                if isinstance(value, list) and value and all(isinstance(row, dict) for row in value)]

    def show_plot(self) -> None:
        plot = self.query_one("#result-plot", LinePlot)
        if not self.plots:
            plot.title = "(this result has no plots)"
            plot.set_series([])
            return
        view = self.plots[self.plot_index % len(self.plots)]
        plot.title = f"{view.title}  ({self.plot_index % len(self.plots) + 1}/{len(self.plots)}, n: next)"
        plot.x_label = view.x_label
        plot.set_series(view.series)

    def set_status(self, text: str) -> None:
        """The outcome of s, c or f: on the status line at the top, and as a notification, which shows
        wherever the operator has scrolled to."""
        tell(self.query_one("#results-status", Static), text)

    def check_action(self, action: str, parameters) -> bool | None:
        # flash is offered only where the device can store a calibration
        return can_flash(self.session) if action == "flash" else True

    def action_next_plot(self) -> None:
        self.plot_index += 1
        self.show_plot()

    # ------------------------------------------------------------------ save
    def action_save(self) -> None:
        if self.profile is None:
            self.set_status("[red]there is no profile to save[/] (see the message above)")
            return
        self.save_flow()

    @work(exclusive=True, group="save")
    async def save_flow(self) -> None:
        await self.save_result()

    def unsaved_result(self) -> bool:
        """A profile was made and is not saved (a result that makes none has nothing to save)."""
        return self.profile is not None and self.saved_path is None

    async def save_result(self) -> bool:
        """Ask where, then save the profile (asking before replacing a file); True once it is written."""
        from accelrig.profiles import save_profile
        from accelrig.profiles.store import ProfileStore

        if self.saved_path is not None:
            default = str(self.saved_path)   # saving again replaces it (after asking), not a second file
        elif self.app.profile_dir is not None:
            default = str(Path(self.app.profile_dir) / default_profile_name(self.result, self.session))
        else:
            try:
                default = str(ProfileStore().path_for(self.profile))   # the store, where the CLI finds it
            except AccelrigError:
                default = str(ProfileStore().root / default_profile_name(self.result, self.session))
        path = await self.app.push_screen_wait(PathScreen("Save the profile to (the store by default):", default))
        if path is None:
            self.set_status("not saved")
            return False
        target = Path(path).expanduser()
        if target.exists():
            if not await self.app.push_screen_wait(ConfirmScreen(f"{target} exists. Overwrite it?", "Overwrite", "Keep it")):
                self.set_status(f"not saved: {target} kept as it was")
                return False
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            save_profile(self.profile, target, overwrite=True)
        except (AccelrigError, OSError) as exc:
            self.set_status(f"[red]not saved:[/] {exc}")
            return False
        self.saved_path = target
        self.set_status(f"[green]profile saved to[/] {target}")
        return True

    # ------------------------------------------------------------------ certificate
    def device_facts(self) -> dict | None:
        return self.session.info.to_dict() if self.session is not None and self.session.info else None

    def action_certificate(self) -> None:
        self.certificate_flow()

    @work(exclusive=True, group="certificate")
    async def certificate_flow(self) -> None:
        written = await write_certificate_flow(self, self.result, self.recording, self.device_facts(), self.set_status)
        if written is not None:
            self.certificate_path = written

    # ------------------------------------------------------------------ flash
    def action_flash(self) -> None:
        if not can_flash(self.session):
            self.set_status("[red]this device cannot store a calibration:[/] keep the profile (s) and apply it "
                            "to the stream instead")
            return
        if self.profile is None:
            self.set_status("[red]there is no profile to flash[/]")
            return
        if self.flashing:
            self.set_status("a flash is under way: wait for it to end")
            return
        self.flashing = True
        self.flash_flow()

    @work(group="flash")
    async def flash_flow(self) -> None:
        """The flash as ``accelrig flash`` makes it: the stream stops (a device flashes only when freshly
        opened: a firmware refuses while it streams), the device is opened afresh, the plan is read and
        shown, the operator agrees, it is written and read back; then the stream is opened again.
        Each step is said on the status line."""
        try:
            if self.unsaved_result():
                choice = await self.app.push_screen_wait(ChoiceScreen(
                    "The profile is not saved. The flash stops the stream, opens the device afresh and opens "
                    "the stream again after it (the captured data are kept).",
                    [("save", "Save the profile, then flash it"), ("flash", "Flash it without saving"),
                     ("stay", "Do not flash")]))
                if choice == "save":
                    if not await self.save_result():
                        return
                elif choice != "flash":
                    self.set_status("not flashed")
                    return
            url = self.session.url
            self.set_status(f"stopping the stream of {escape(url)} for the flash (the captured data are kept) ...")
            await asyncio.to_thread(self.session.stop)
            outcome, written = "", False
            try:
                outcome, written = await self.flash_fresh(url)
            finally:
                await self.reopen_stream(url, outcome, written)
        finally:
            self.flashing = False

    async def flash_fresh(self, url: str) -> tuple[str, bool]:
        """Open ``url`` afresh, plan, ask, write and verify, as the command does; the outcome's text (still
        shown once the stream is open again) and whether anything was written."""
        driver = None
        try:
            self.set_status(f"opening {escape(url)} afresh for the flash ...")
            driver = driver_for(url)
            await asyncio.to_thread(driver.__enter__)
            self.set_status("reading the device to plan the flash ...")
            plan = await asyncio.to_thread(plan_flash, driver, self.profile, force_hint="")  # no force in the TUI
            # the notifications of the steps would lie over the plan's right half while it asks
            await self.clear_notifications()
            question = ConfirmScreen("Write to the device?", "Write", "Cancel",
                                     details=escape(format_plan(plan, width=DIALOG_TEXT_WIDTH)))
            if not await self.app.push_screen_wait(question):
                return "flash cancelled: nothing was written", False
            self.set_status("writing, then reading back to verify ...")
            report = await asyncio.to_thread(driver.flash, plan)
        except AccelrigError as exc:
            return f"[red]cannot flash:[/] {escape(str(exc))}", False
        finally:
            if driver is not None:
                await asyncio.to_thread(driver.close)
        verdict = "[green]written and verified[/]" if report.verified else "[red]written but NOT verified[/]"
        return f"{verdict}: " + escape("; ".join(f"{w.target} {w.current}" for w in report.readback)
                                       + ("\n" + "\n".join(report.notes) if report.notes else "")), True

    async def clear_notifications(self) -> None:
        """Clear the notifications, those still on their way too: notify posts a message, so a clear made at
        once can come before the last step's note (on a loaded machine) and leave it over the plan.  The
        clear is queued behind them."""
        cleared = asyncio.Event()

        def clear() -> None:
            self.app.clear_notifications()
            cleared.set()

        self.app.call_later(clear)
        await cleared.wait()

    async def reopen_stream(self, url: str, outcome: str, written: bool) -> None:
        """Open the stream again after a flash (or an attempt), as the live view had it.  A device whose store
        is volatile (chip offset registers, reset by the reopen) is reopened with profile=PATH when the profile
        is saved, so the open writes it again, as every later connect with that URL does."""
        if not self.app.is_running:
            return   # the app quit during the flash: nothing to stream to
        reapplying = url_reapplying(url, self.saved_path) if written and self.saved_path is not None else None
        stream_url = reapplying or url
        outcome = f"{outcome}\n" if outcome else ""
        self.set_status(f"{outcome}opening the stream of {escape(stream_url)} again ...")
        try:
            session = await asyncio.to_thread(Session.open_and_start, stream_url, self.app.buffer_seconds,
                                              prepare=flash_url_profile)
        except AccelrigError as exc:
            self.set_status(f"{outcome}[red]the stream could not be opened again:[/] {escape(str(exc))} "
                            "(escape twice, then c on the live view connects)")
            return
        if not self.app.is_running:
            session.stop()
            return
        self.session = session
        self.app.use_session(session)
        again = (f"streaming again from {escape(stream_url)}: the profile is written on every open of this URL "
                 "(the chip forgets it at reset)" if reapplying else "streaming again")
        if written and reapplying is None and url_reapplying(url, "PROFILE") is not None:
            again += (": the chip forgot the offsets at this reopen; save the profile and flash again to have "
                      "them written on every open (profile=PATH)")
        self.set_status(f"{outcome}{again}")
