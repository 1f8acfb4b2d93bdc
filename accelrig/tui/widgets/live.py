"""The live picture of a session: axes traces, magnitude, rate, drops, gaps, saturation."""

from __future__ import annotations

import numpy as np
from rich.markup import escape
from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import Sparkline, Static

from accelrig.acquisition.ringbuffer import Reader
from accelrig.acquisition.session import Session, State
from accelrig.tui.widgets.plot import LinePlot, Series
from accelrig.units import STANDARD_GRAVITY, saturated

AXIS_STYLES = ("red", "green", "dodger_blue1")
PLOT_POINTS = 600  # points handed to a plot per refresh; more than any terminal shows


def shortened(text: str, width: int) -> str:
    """``text`` cut to ``width`` columns with an ellipsis at the end (at least its first character shows):
    a device URL on a one-row status line, whose counters must stay whole."""
    if len(text) <= width:
        return text
    return text[:max(width - 1, 1)] + "…"


class LiveWindow:
    """The last ``seconds`` of samples, refilled from a ring-buffer reader (no UI here).

    A slow refresh is never a problem: the reader says how many samples it
    lost and the window simply starts later.
    """

    def __init__(self, reader: Reader, seconds: float, max_samples: int):
        self.reader = reader
        self.seconds = seconds
        self.max_samples = max_samples
        self.t = np.zeros(0)
        self.counts = np.zeros((0, 3), dtype=np.int16)
        self.scale = reader.buffer.scale

    def update(self) -> int:
        """Pull what arrived; returns the number of new samples."""
        chunk = self.reader.read()
        if chunk.n:
            self.t = np.concatenate([self.t, chunk.t])[-self.max_samples:]
            self.counts = np.concatenate([self.counts, chunk.counts])[-self.max_samples:]
            keep = self.t >= self.t[-1] - self.seconds
            self.t, self.counts = self.t[keep], self.counts[keep]
        return chunk.n

    @property
    def acc(self) -> np.ndarray:
        return self.counts.astype(float) * self.scale

    @property
    def saturated(self) -> int:
        """Samples in the window with an axis saturated."""
        return int(np.count_nonzero(saturated(self.counts).any(axis=1)))


def _decimate(n: int, points: int) -> np.ndarray:
    return np.linspace(0, n - 1, min(n, points)).astype(int) if n else np.zeros(0, dtype=int)


class LiveView(Vertical):
    """Shows one Session; ``refresh_from(session)`` is called on the screen's timer."""

    def __init__(self, window_seconds: float = 5.0, *, id: str | None = None):
        super().__init__(id=id)
        self.window_seconds = window_seconds
        self._session: Session | None = None
        self._window: LiveWindow | None = None
        self._last_stats = None
        self._device_text: str | None = None   # the device line as last drawn

    def compose(self) -> ComposeResult:
        yield Static("", id="device-line")
        yield LinePlot("axes (m/s²)", x_label="time (s)", id="axes-plot")
        yield Static("", id="axes-now")
        # the bars have no axis of their own: this line says what they are and the range they span
        yield Static(f"|a| over the last {self.window_seconds:g} s (m/s²), bars below", id="magnitude-label")
        yield Sparkline([], id="magnitude")
        yield Static("", id="stats-line")
        yield Static("", id="warning-line")

    def refresh_from(self, session: Session | None, connect_error: str | None = None) -> None:
        device = self.query_one("#device-line", Static)
        if session is None or session.info is None:
            device.update(connect_error or "connecting ...")
            self._device_text = None
            return
        if session is not self._session:
            self._session = session
            self._last_stats = None
            info = session.info
            self._window = LiveWindow(session.reader(from_oldest=True), self.window_seconds,
                                      int(info.nominal_rate * self.window_seconds * 1.2) + 64)
            plot = self.query_one("#axes-plot", LinePlot)
            limit = info.range_g * STANDARD_GRAVITY
            plot.y_range = (-limit, limit)
        info = session.info
        # one row: a URL too long for it is cut with an ellipsis (the connect screen shows it whole); the
        # chip, identity, range and rate stay whole.  Before the first layout the width is not known yet.
        facts = f"  {info.chip}  id {info.identity}  ±{info.range_g:g} g  {info.nominal_rate:g} Hz"
        width = device.content_size.width
        url = shortened(info.url, width - len(facts)) if width else info.url
        line = f"[b]{escape(url)}[/b]{escape(facts)}"
        if line != self._device_text:
            self._device_text = line
            device.update(line)
        window = self._window
        new = window.update()
        stats = session.stats()
        if not new and stats == self._last_stats:
            return  # nothing changed: do not redraw
        self._last_stats = stats
        plot = self.query_one("#axes-plot", LinePlot)
        acc = window.acc
        # a fixed number of points, not the widget's width: the first draw may come before layout
        idx = _decimate(window.t.size, PLOT_POINTS)
        t = window.t[idx] - (window.t[-1] if window.t.size else 0.0)
        plot.set_series([
            Series(t, acc[idx, axis], AXIS_STYLES[axis], label) for axis, label in enumerate(("x", "y", "z"))
        ])
        magnitude = np.linalg.norm(acc, axis=1)
        now = self.query_one("#axes-now", Static)
        if acc.shape[0]:
            recent = acc[-max(int(0.5 * session.info.nominal_rate), 1):].mean(axis=0)
            now.update(
                f"[red]x {recent[0]:+8.3f}[/]  [green]y {recent[1]:+8.3f}[/]  "
                f"[dodger_blue1]z {recent[2]:+8.3f}[/]  |a| {np.linalg.norm(recent):7.3f} m/s²"
            )
        self.query_one("#magnitude", Sparkline).data = magnitude[_decimate(magnitude.size, PLOT_POINTS)].tolist()
        if magnitude.size:
            self.query_one("#magnitude-label", Static).update(
                f"|a| over the last {self.window_seconds:g} s (m/s²), bars below: lowest {magnitude.min():.3f}, "
                f"highest {magnitude.max():.3f}")
        self.query_one("#stats-line", Static).update(
            f"{_state_text(stats.state)}  rate {stats.delivered_rate:7.1f} Hz  "
            f"samples {stats.samples}  drops {stats.missing}  gaps {stats.gap_events}"
        )
        warnings = []
        if stats.state == State.DISCONNECTED:
            warnings.append(f"DEVICE DISCONNECTED: {stats.last_error}")
        elif stats.state == State.FAILED:
            warnings.append(f"ACQUISITION FAILED: {stats.last_error}")
        if window.saturated:
            warnings.append(f"SATURATION: {window.saturated} samples at full scale in the last "
                            f"{self.window_seconds:g} s; use a larger range")
        line = self.query_one("#warning-line", Static)
        line.update("\n".join(warnings))
        line.set_class(bool(warnings), "alarm")


def _state_text(state: State) -> str:
    return {
        State.STREAMING: "[green]● streaming[/]",
        State.ENDED: "[yellow]■ source ended[/]",
        State.DISCONNECTED: "[red]✖ disconnected[/]",
        State.FAILED: "[red]✖ failed[/]",
        State.STOPPED: "■ stopped",
    }.get(state, state.value)
