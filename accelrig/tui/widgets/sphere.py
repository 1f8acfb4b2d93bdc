"""Where on the sphere the still poses point: two hemisphere maps and the counts, for the any-orientation flow."""

from __future__ import annotations

import numpy as np
from textual.widgets import Static

WIDTH, HEIGHT = 17, 7      # one hemisphere disk in terminal cells (cells are about twice as tall as wide)


def hemisphere_rows(directions: np.ndarray, upper: bool) -> list[str]:
    """One hemisphere (z >= 0 or z < 0) seen from its pole, Lambert equal-area (equal areas of the sphere are
    equal areas of the disk, so a bare patch looks as large as it is): '·' not reached, '●' a pose, '◉' several."""
    counts = np.zeros((HEIGHT, WIDTH), dtype=int)
    for d in np.asarray(directions, dtype=float).reshape(-1, 3):
        if (d[2] >= 0) != upper:
            continue
        polar = np.arccos(min(abs(d[2]), 1.0))
        horizontal = np.hypot(d[0], d[1])
        r = min(np.sqrt(2.0) * np.sin(polar / 2.0), 1.0)   # 0 at the pole, 1 at the equator
        ux, uy = (d[0] / horizontal, d[1] / horizontal) if horizontal > 0 else (0.0, 0.0)
        col = int(round((WIDTH - 1) / 2 * (1 + r * ux)))
        row = int(round((HEIGHT - 1) / 2 * (1 - r * uy)))
        counts[row, col] += 1
    rows = []
    for row in range(HEIGHT):
        line = []
        for col in range(WIDTH):
            x = (col - (WIDTH - 1) / 2) / ((WIDTH - 1) / 2)
            y = (row - (HEIGHT - 1) / 2) / ((HEIGHT - 1) / 2)
            n = counts[row, col]
            line.append("◉" if n > 1 else "●" if n else "·" if x * x + y * y <= 1.0 + 1e-9 else " ")
        rows.append("".join(line))
    return rows


def coverage_text(orientations: dict) -> str:
    """The two hemisphere maps side by side and the counts (the procedure's ``orientations``)."""
    up = hemisphere_rows(orientations["directions"], True)
    down = hemisphere_rows(orientations["directions"], False)
    lines = [f"{'+z up (sensor z axis up)':<{WIDTH + 4}}  -z up"]
    lines += [f"{a}    {b}" for a, b in zip(up, down, strict=True)]
    n, needed, more = orientations["n_distinct"], orientations["needed"], orientations["more"]
    asked = orientations.get("more_asked", 0)
    need = f"{more} more needed" if more else f"enough; {asked} more asked" if asked else "enough"
    # "11 of 9" read as a count out of a total: say how many are needed instead
    lines.append(f"distinct orientations {n}, {needed} needed ({need}; within {orientations['distinct_deg']:g}° counts once)   "
                 f"octants {orientations['octants']} of 8   poses {orientations['n_poses']}")
    return "\n".join(lines)


class SphereMap(Static):
    """Shows the static procedure's ``orientations``; holds no state of its own."""

    def show(self, orientations: dict) -> None:
        self.update(coverage_text(orientations))
