"""The commands the README and docs/ show are true as written: on a fresh machine after the set-up, and a
simulated recording they show is long enough for what follows it."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from accelrig.acquisition.url import DeviceURL

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.S | re.M)
RECORD = re.compile(r"accelrig record '(sim://[^']+)'(?P<rest>[^\n#]*)")


def test_the_readme_activates_the_venv_before_its_commands():
    """A bare `accelrig` runs the program only with .venv activated (a pyenv shim answers it otherwise)."""
    for block in FENCE.findall((ROOT / "README.md").read_text(encoding="utf-8")):
        lines = [line.strip() for line in block.splitlines()]
        for i, line in enumerate(lines):
            if line.startswith("accelrig "):
                assert any(before.startswith((". .venv/bin/activate", "source .venv/bin/activate"))
                           for before in lines[:i]), f"README runs {line!r} without activating .venv"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_a_simulated_recording_shown_runs_the_whole_script(doc):
    """`record 'sim://static?seed=1' --seconds 60` cut the 87 s script (11 of 15 holds): the calibration after
    it said 'drift shape not checked'.  A --seconds shown holds the rig's whole script."""
    from accelrig_drivers.sim import build_device

    for m in RECORD.finditer(doc.read_text(encoding="utf-8")):
        seconds = re.search(r"--seconds\s+(\S+)", m["rest"])
        if seconds is None:
            continue
        device, _ = build_device(DeviceURL.parse(m[1]))
        duration = getattr(device.rig, "duration", None)
        if duration is not None and duration != float("inf"):
            assert float(seconds[1]) >= duration, (doc.name, m[0], duration)
