"""A small line plot drawn with Unicode braille dots (2 x 4 dots per cell).

Textual has no plotting widget and a plotting dependency would be heavy for a
few curves; braille gives eight dots per terminal cell, enough to see a trace,
a decay or a frequency response.  Each series has its own colour; where two
series share a cell the one drawn last wins.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass

import numpy as np
from rich.text import Text
from textual.widget import Widget

_BRAILLE_BASE = 0x2800
# dot bit for (column 0..1, row 0..3) inside one braille cell
_DOT_BITS = np.array([[0x01, 0x02, 0x04, 0x40], [0x08, 0x10, 0x20, 0x80]])


@dataclass
class Series:
    x: np.ndarray
    y: np.ndarray
    style: str
    label: str = ""
    join: bool = True   # draw lines between points (False: points only)


class LinePlot(Widget):
    """Plots one or more series; the y range is fixed (``y_range``) or follows the data."""

    DEFAULT_CSS = """
    LinePlot { height: 9; }
    """

    def __init__(self, title: str = "", y_range: tuple[float, float] | None = None, x_label: str = "",
                 *, id: str | None = None, classes: str | None = None):
        super().__init__(id=id, classes=classes)
        self.title = title            # what is plotted, with the y unit: "wheel speed (rad/s)"
        self.y_range = y_range
        self.x_label = x_label        # the x quantity with its unit: "time (s)", "frequency (Hz)"
        self.series: list[Series] = []

    def set_series(self, series: list[Series]) -> None:
        self.series = series
        self.refresh()

    def render(self) -> Text:
        width, height = self.size.width, self.size.height
        label_width = 8
        text = Text(no_wrap=True, overflow="crop")
        # a title and legend wider than the plot take the rows they need, and the dots give them up: a header
        # left to wrap by itself pushed the x axis row (its range and label) off the bottom at 80 columns
        header = header_lines(self.title, [(s.label, s.style) for s in self.series if s.label], max(width, 1))
        plot_w, plot_h = max(width - label_width, 1), max(height - 1 - len(header), 1)
        text.append_text(Text("\n").join(header))
        finite = [s for s in self.series if s.x.size]
        if not finite:
            text.append("\n(no data yet)", style="dim")
            return text
        xs = np.concatenate([s.x for s in finite])
        ys = np.concatenate([s.y for s in finite])
        good = np.isfinite(xs) & np.isfinite(ys)
        if not good.any():
            text.append("\n(no finite data)", style="dim")
            return text
        x0, x1 = float(xs[good].min()), float(xs[good].max())
        if self.y_range is not None:
            y0, y1 = self.y_range
        else:
            y0, y1 = float(ys[good].min()), float(ys[good].max())
            pad = 0.05 * (y1 - y0) if y1 > y0 else max(abs(y0) * 0.05, 1e-9)
            y0, y1 = y0 - pad, y1 + pad
        if x1 <= x0:
            x1 = x0 + 1.0
        text.append("\n")
        dots_w, dots_h = plot_w * 2, plot_h * 4
        cells = np.zeros((plot_h, plot_w), dtype=np.int32)
        owner = np.full((plot_h, plot_w), -1, dtype=np.int32)
        for index, s in enumerate(finite):
            ok = np.isfinite(s.x) & np.isfinite(s.y)
            if not ok.any():
                continue
            px = np.round((s.x[ok] - x0) / (x1 - x0) * (dots_w - 1)).astype(int)
            py = np.round((y1 - np.clip(s.y[ok], y0, y1)) / (y1 - y0) * (dots_h - 1)).astype(int)
            if s.join and px.size > 1:
                px, py = _join(px, py)
            px = np.clip(px, 0, dots_w - 1)
            py = np.clip(py, 0, dots_h - 1)
            rows, cols = py // 4, px // 2
            bits = _DOT_BITS[px % 2, py % 4]
            np.bitwise_or.at(cells, (rows, cols), bits)
            owner[rows, cols] = index
        # the top row's first dot is y1, the bottom row's last dot y0; a middle row is labelled at its centre
        y_ticks = {0: y1, plot_h - 1: y0}
        if plot_h >= 5:
            mid = (plot_h - 1) // 2
            y_ticks[mid] = y1 - (y1 - y0) * (4 * mid + 1.5) / (dots_h - 1)
        for row in range(plot_h):
            label = _tick(y_ticks[row]) if row in y_ticks else ""
            text.append(f"{label:>7} ", style="dim")
            # one append per run of cells of the same series keeps rendering cheap
            col = 0
            while col < plot_w:
                who = int(owner[row, col]) if cells[row, col] else -1
                end = col + 1
                while end < plot_w and (int(owner[row, end]) if cells[row, end] else -1) == who:
                    end += 1
                run = "".join(chr(_BRAILLE_BASE + int(b)) if b else " " for b in cells[row, col:end])
                text.append(run, style=finite[who].style if who >= 0 else "")
                col = end
            text.append("\n")
        text.append(" " * label_width + x_axis_row(x0, x1, self.x_label, plot_w), style="dim")
        return text


def header_lines(title: str, legend: list[tuple[str, str]], width: int) -> list[Text]:
    """The title (bold, wrapped at its spaces) and then the legend's "━ label" entries, packed into lines of
    at most ``width`` cells; an entry starts a new line rather than being split."""
    lines = [Text(line, style="bold") for line in textwrap.wrap(title, width) or [""]]
    for label, style in legend:
        entry = "━ " + label
        line = lines[-1]
        if line.plain and line.cell_len + 2 + len(entry) > width:
            lines.append(line := Text())
        if line.plain:
            line.append("  ")
        line.append(entry[:width], style=style)
    return lines


def _tick(value: float) -> str:
    return f"{value:.3g}" if abs(value) >= 1e-12 else "0"


def x_axis_row(x0: float, x1: float, label: str, width: int) -> str:
    """The row under the plot: x0 under the first column, x1 ending under the last, the label centred."""
    left, right = _tick(x0), _tick(x1)
    inner = width - len(left) - len(right)
    name = label if len(label) + 2 <= inner else label[:max(inner - 2, 0)]
    if inner < 1:
        return (left + " " + right)[:width]
    return left + name.center(inner) + right


def _join(px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fill in the dots between consecutive points so a fast change stays a line."""
    steps = np.maximum(np.abs(np.diff(px)), np.abs(np.diff(py)))
    steps = np.maximum(steps, 1)
    if steps.max() == 1:
        return px, py
    out_x, out_y = [px[:1]], [py[:1]]
    # vectorised interpolation: for each segment, steps[i] points excluding its start
    seg = np.repeat(np.arange(steps.size), steps)
    frac = (np.arange(seg.size) - np.repeat(np.cumsum(steps) - steps, steps) + 1) / np.repeat(steps, steps)
    out_x.append(np.round(px[seg] + frac * (px[seg + 1] - px[seg])).astype(int))
    out_y.append(np.round(py[seg] + frac * (py[seg + 1] - py[seg])).astype(int))
    return np.concatenate(out_x), np.concatenate(out_y)
