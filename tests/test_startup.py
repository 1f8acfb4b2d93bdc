"""Start-up stays light: the CLI imports a command's machinery only when that command runs."""

import json
import subprocess
import sys


def imported_after(code: str) -> list[str]:
    """Modules a fresh interpreter holds after running ``code``."""
    probe = code + "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))\n"
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.splitlines()[-1])


def test_help_imports_neither_scipy_nor_textual_nor_a_driver():
    modules = imported_after("from accelrig.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass")
    heavy = [m for m in modules if m.split(".")[0] in ("scipy", "textual", "accelrig_drivers")]
    assert heavy == []
    assert "accelrig.commands.record" not in modules  # no command module either


def test_driver_for_imports_only_the_driver_of_its_scheme():
    modules = imported_after("from accelrig.acquisition.driver import driver_for\ndriver_for('replay://x.csv')")
    assert [m for m in modules if m.startswith("accelrig_drivers.")] == ["accelrig_drivers.replay"]


def test_a_procedure_commands_help_loads_only_the_settings_it_renders():
    """The flags come from the procedures' light settings modules; numpy, scipy and the fits load in run()."""
    for argv in (["calibrate", "static", "--help"], ["calibrate", "wheel", "--help"], ["plan", "wheel", "--help"]):
        modules = imported_after(f"from accelrig.cli import main\ntry:\n    main({argv!r})\nexcept SystemExit:\n    pass")
        heavy = [m for m in modules if m.split(".")[0] in ("numpy", "scipy", "textual")
                 or (m.startswith("accelrig.procedures.") and m.count(".") > 2 and not m.endswith(".settings"))]
        assert heavy == [], (argv, heavy)
        assert "accelrig.procedures.static.settings" in modules or argv[0] == "plan"
