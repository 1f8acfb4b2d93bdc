"""Text tables that fit a terminal's width: the one rule for choosing columns, for the CLI and the TUI.

At 80 columns the daemon's and the fleet's tables are wider than the screen.  ``columns_that_fit`` picks
the columns that fit whole, in order of importance (the TUI's FittedTable shows those and names the rest);
``fitted_lines`` prints every column as plain text by stacking the ones that do not fit in further tables
under the first, each led by the row's name, so nothing is cut at the right edge and nothing is lost.
"""

from __future__ import annotations

from collections.abc import Sequence

TERMINAL_WIDTH = 80   # what a plain-text table is fitted to: the terminal every operator has


def columns_that_fit(titles: Sequence[str], rows: Sequence[Sequence[str]], width: int,
                     priority: Sequence[int], keep: int = 2, padding: int = 1) -> list[int]:
    """Indices of the columns to show, in the table's order: all when they fit in ``width`` cells, else
    the most important (``priority``: indices, most important first) that fit whole; the first ``keep``
    of ``priority`` are always shown (the table scrolls sideways when even they are too wide).  Each
    column takes its widest cell plus ``padding`` either side."""
    def cells(i: int) -> int:
        return max([len(str(titles[i]))] + [len(str(row[i])) for row in rows]) + 2 * padding

    if sum(cells(i) for i in range(len(titles))) <= width:
        return list(range(len(titles)))
    chosen, used = set(), 0
    for rank, i in enumerate(priority):
        if rank < keep or used + cells(i) <= width:
            chosen.add(i)
            used += cells(i)
    return sorted(chosen)


def fitted_lines(titles: Sequence[str], rows: Sequence[Sequence[str]], priority: Sequence[int],
                 width: int = TERMINAL_WIDTH) -> list[str]:
    """Every column of the table as lines of at most ``width`` characters (unless one cell alone is wider):
    the columns that fit (``columns_that_fit``, two spaces between them), then the rest in further tables
    under it, a blank line before each, each led by the first column of ``priority`` (the row's name)."""
    key, left = priority[0], list(priority[1:])
    lines: list[str] = []
    while left or not lines:
        part = [key, *left]   # in order of importance
        # each column costs its width + 2 (padding 1): n columns joined by two spaces take 2 less
        shown = columns_that_fit([titles[i] for i in part], [[row[i] for i in part] for row in rows], width + 2,
                                 range(len(part)))
        chosen = sorted(part[j] for j in shown)   # in the table's order
        left = [i for i in left if i not in chosen]
        widths = {i: max([len(str(titles[i]))] + [len(str(row[i])) for row in rows]) for i in chosen}
        if lines:
            lines.append("")
        lines += ["  ".join(str(cells[i]).ljust(widths[i]) for i in chosen).rstrip() for cells in [titles, *rows]]
    return lines
