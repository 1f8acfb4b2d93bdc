"""The key footer every screen shows."""

from __future__ import annotations

from textual.widgets import Footer


class KeyFooter(Footer):
    """Compact, and without the command palette's key: the keys an operator needs (and ? and q) fit an
    80-column terminal, where the padded footer cut them off.  ctrl+p still opens the palette."""

    def __init__(self) -> None:
        super().__init__(show_command_palette=False, compact=True)
