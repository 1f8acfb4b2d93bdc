"""Status tables that stay readable in a narrow terminal: the columns that fit, the most important first.

At 80 columns the daemon's and the fleet's tables are wider than the screen, and a DataTable would cut
them at the right edge (a "missing" column read as "mis").  ``FittedTable`` shows the columns that fit
whole, chosen in order of importance and shown in the table's own order, keeps the first column in
place when the table must scroll sideways anyway, and says which columns it left out.
"""

from __future__ import annotations

from collections.abc import Sequence

from textual.message import Message
from textual.widgets import DataTable

from accelrig.tables import columns_that_fit  # the one rule, shared with the CLI's tables


class FittedTable(DataTable):
    """A read-only table redrawn whole (``show``) with the columns that fit its width.

    Posts ``LeftOut`` whenever the columns it leaves out change (its first real width comes with a resize
    after the screen mounted it): a note that says them listens to that, not to the screen's own resize,
    which can come before the table's."""

    class LeftOut(Message):
        def __init__(self, table: FittedTable, left_out: list[str]):
            super().__init__()
            self.table, self.left_out = table, left_out

    def __init__(self, priority: Sequence[int], **kwargs):
        super().__init__(show_cursor=False, zebra_stripes=True, fixed_columns=1, **kwargs)
        self.priority = list(priority)
        self.shown: list[int] = []
        self.left_out: list[str] = []          # titles of the columns not shown at this width
        self._last: tuple[list[str], list[list[str]], list[str]] | None = None

    def show(self, titles: Sequence[str], rows: Sequence[Sequence[str]], keys: Sequence[str]) -> None:
        """Redraw with ``rows`` (cells in the order of ``titles``), row keys ``keys``."""
        self._last = (list(titles), [list(r) for r in rows], list(keys))
        # a vertical scrollbar may take two cells once there are more rows than lines
        width = max(self.size.width - 2, 0) if self.size.width else 10**6
        shown = columns_that_fit(titles, rows, width, [i for i in self.priority if i < len(titles)])
        if shown != self.shown or len(self.columns) != len(shown):
            self.clear(columns=True)
            for i in shown:
                self.add_column(str(titles[i]), key=str(i))
            self.shown = shown
        else:
            self.clear()
        for row, key in zip(rows, keys, strict=True):
            self.add_row(*(row[i] for i in shown), key=key)
        left_out = [str(titles[i]) for i in range(len(titles)) if i not in shown]
        if left_out != self.left_out:
            self.left_out = left_out
            self.post_message(self.LeftOut(self, left_out))

    def on_resize(self) -> None:
        if self._last is not None:
            self.show(*self._last)
