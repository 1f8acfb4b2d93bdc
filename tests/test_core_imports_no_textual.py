"""The core (accelrig minus accelrig.tui) never imports textual.

Kept beside the import contract "Only the TUI imports textual" (pyproject.toml), which
does not cover it fully: the contract reads import statements, so it cannot see the CLI
loading its commands with importlib.import_module (build_parser below), nor textual
pulled in through a third-party package; and it lists its source modules, where this
walks every package, new ones included.  The contract in turn sees function-level
imports this never executes.
"""

import pkgutil
import subprocess
import sys

import accelrig
import accelrig_drivers


def test_core_modules_import_without_textual():
    names = ["accelrig", "accelrig_drivers"]
    for package in (accelrig, accelrig_drivers):
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            if info.name == "accelrig.tui" or info.name.startswith("accelrig.tui."):
                continue
            if info.name.endswith(".__main__"):  # runs the CLI when imported
                continue
            names.append(info.name)
    assert "accelrig.acquisition.session" in names and "accelrig.commands.tui" in names
    code = (
        "import importlib, sys\n"
        f"for name in {names!r}:\n"
        "    importlib.import_module(name)\n"
        "    assert 'textual' not in sys.modules, name + ' imported textual'\n"
        "from accelrig.cli import build_parser\n"
        "build_parser()\n"
        "assert 'textual' not in sys.modules, 'building the CLI imported textual'\n"
        "print(len(sys.modules))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr


def test_the_tui_does_import_textual():
    # the check above would pass vacuously if the probe could not see textual at all
    code = "import sys, accelrig.tui.app; print('textual' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip() == "True", result.stderr
