"""The braille line plot: dots land where the data say."""

import asyncio

import numpy as np
from textual.app import App  # noqa: E402

from accelrig.tui.widgets.plot import LinePlot, Series, _join  # noqa: E402

BASE = 0x2800


class PlotApp(App):
    def compose(self):
        yield LinePlot("test", y_range=(0.0, 1.0), id="plot")


def rows_of(plot) -> list[str]:
    return plot.render().plain.split("\n")[1:-1]  # drop the title row and the x axis row


def test_a_rising_line_goes_from_bottom_left_to_top_right():
    async def run():
        app = PlotApp()
        async with app.run_test(size=(28, 6)) as pilot:
            plot = app.query_one("#plot")
            plot.styles.height = 5
            plot.x_label = "time (s)"
            await pilot.pause()
            plot.set_series([Series(np.array([0.0, 1.0]), np.array([0.0, 1.0]), "red")])
            await pilot.pause()
            rows = rows_of(plot)
            cells = [row[8:] for row in rows]  # after the 8-character axis labels
            width = plot.size.width - 8
            assert len(cells) == plot.size.height - 2 == 3
            # bottom-left cell holds the lowest-left dot (dot 7: bit 0x40), top-right the highest-right (dot 4: 0x08)
            assert ord(cells[-1][0]) - BASE & 0x40
            assert ord(cells[0][width - 1]) - BASE & 0x08
            # joined: every column has a dot somewhere
            for col in range(width):
                assert any(ord(c[col]) > BASE for c in cells if col < len(c))
            assert rows[0].strip().startswith("1") and rows[-1].strip().startswith("0")
            # under the plot: x at both ends with the quantity and its unit between them
            axis = plot.render().plain.split("\n")[-1]
            assert axis[8:].startswith("0") and axis.rstrip().endswith("1") and "time (s)" in axis

    asyncio.run(run())


def test_points_only_series_are_not_joined_and_nan_is_skipped():
    px, py = _join(np.array([0, 10]), np.array([0, 0]))
    assert list(px) == list(range(11)) and set(py) == {0}

    async def run():
        app = PlotApp()
        async with app.run_test(size=(28, 6)) as pilot:
            plot = app.query_one("#plot")
            plot.set_series([Series(np.array([0.0, 0.5, 1.0]), np.array([0.5, np.nan, 0.5]), "red", join=False)])
            await pilot.pause()
            dots = sum(ord(ch) > BASE for row in rows_of(plot) for ch in row)
            assert dots == 2

    asyncio.run(run())


def test_result_arrays_are_drawn_against_their_time_or_frequency_with_units():
    from accelrig.tui.screens.results import ARRAY_UNITS, plot_series, plottable

    arrays = {"t": np.arange(5.0), "residuals": np.zeros((5, 3)), "speed_time": np.arange(3.0) + 0.5,
              "speed_samples": np.array([9.0, 8.5, 8.1]), "pose_means": np.ones((6, 3))}
    assert plottable(arrays) == ["residuals", "speed_samples", "pose_means"]
    label, series = plot_series("speed_samples", arrays)
    assert label == "time (s)" and np.array_equal(series[0].x, arrays["speed_time"])
    label, series = plot_series("pose_means", arrays)
    assert label == "pose number" and series[0].x.tolist() == [1, 2, 3, 4, 5, 6] and len(series) == 3
    assert ARRAY_UNITS["speed_samples"] == "rad/s" and ARRAY_UNITS["residuals"] == "m/s²"


def test_a_title_wider_than_the_plot_wraps_and_the_x_axis_stays_on_screen():
    """At 80 columns the results' plot title and legend take two rows: the dots give one up, not the x axis."""
    from textual.geometry import Region

    async def run():
        app = PlotApp()
        async with app.run_test(size=(76, 10)) as pilot:
            plot = app.query_one("#plot")
            plot.styles.height = 10
            plot.title = "|a| − g per pose (m/s²): after should sit near 0  (1/1, n: next)"
            plot.x_label = "time (s), middle of each pose"
            x = np.linspace(1.89, 64.9, 12)
            plot.set_series([Series(x, np.sin(x), "red", "before"), Series(x, np.cos(x), "green", "after")])
            await pilot.pause()
            # what the screen shows, after Textual has laid the widget's text into its 76 x 10 cells
            shown = ["".join(segment.text for segment in strip) for strip in plot.render_lines(Region(0, 0, 76, 10))]
            assert shown[0].rstrip().endswith("━ before") and shown[1].strip() == "━ after"
            assert "1.89" in shown[-1] and "64.9" in shown[-1] and "time (s), middle of each pose" in shown[-1]
            assert all(len(line.rstrip()) <= 76 for line in shown)

    asyncio.run(run())
