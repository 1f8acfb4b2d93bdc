"""Snapshots of the main screens at fixed sizes.

The device is a seeded, finite simulation at pace=fast: the screens are taken
once it has ended, so every number and trace on them is deterministic.
Regenerate after an intended change with ``pytest --snapshot-update`` and look
at the SVGs before committing them.
"""

import asyncio

import pytest

pytest.importorskip("textual")

from accelrig.acquisition.session import State  # noqa: E402
from accelrig.tui.app import AccelrigApp  # noqa: E402

FINITE = "sim://still?seed=1&pace=fast&seconds=10"


async def until_ended(pilot):
    app = pilot.app
    loop = asyncio.get_running_loop()
    deadline = loop.time() + 10
    while app.session is None or app.session.stats().state != State.ENDED:
        assert loop.time() < deadline, "the simulated device did not end"
        await pilot.pause(0.05)
    await pilot.pause(0.3)  # let the refresh timer draw the final state


def test_live_80x24(snap_compare):
    assert snap_compare(AccelrigApp(device=FINITE, refresh_interval=0.05), terminal_size=(80, 24),
                        run_before=until_ended)


def test_live_120x40(snap_compare):
    assert snap_compare(AccelrigApp(device=FINITE, refresh_interval=0.05), terminal_size=(120, 40),
                        run_before=until_ended)


def test_help_80x24(snap_compare):
    async def open_help(pilot):
        await until_ended(pilot)
        await pilot.press("question_mark")
        await pilot.pause(0.2)

    assert snap_compare(AccelrigApp(device=FINITE, refresh_interval=0.05), terminal_size=(80, 24),
                        run_before=open_help)
