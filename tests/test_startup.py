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


def test_a_static_calibration_does_not_load_scipy_stats(tmp_path):
    """scipy.stats costs ~0.7 s of CPU at import, more than a static calibration's whole analysis: its checks
    take their p-values from accelrig.estimation.distributions (scipy.special) instead."""
    import numpy as np

    from accelrig.recording import write_csv
    from accelrig.sim.device import simulate
    from accelrig.sim.rigs.static import StaticRig
    from accelrig.sim.sensor import SensorModel, SimClock

    rec = simulate(StaticRig(np.random.default_rng(3)),
                   SensorModel(range_g=8.0, noise_density=SensorModel.noise_density_for_sd(0.05, 200.0)),
                   SimClock(200.0), seed=3)
    path = tmp_path / "static.csv"
    write_csv(rec, path)
    for flags in ([], ["--model", "paper", "--method", "paper"]):
        argv = ["calibrate", "static", str(path), "--json", "--no-store", *flags]
        modules = imported_after(f"import contextlib, io\nfrom accelrig.cli import main\n"
                                 f"with contextlib.redirect_stdout(io.StringIO()):\n    assert main({argv!r}) == 0")
        assert "accelrig.procedures.static.procedure" in modules
        assert not [m for m in modules if m.startswith("scipy.stats")], flags


def test_the_light_distributions_equal_scipy_stats():
    import numpy as np
    from scipy import stats

    from accelrig.estimation import distributions

    x = np.array([-1.0, 0.0, 0.3, 2.5, 40.0, 1e3])
    for dof in (1, 2.5, 7, 60):
        np.testing.assert_allclose(distributions.chi2.sf(x, dof), stats.chi2.sf(x, dof), rtol=1e-12)
        np.testing.assert_allclose(distributions.f.sf(x, dof, 11), stats.f.sf(x, dof, 11), rtol=1e-12)
        assert distributions.student_t_quantile(0.977, dof) == stats.t.ppf(0.977, dof)
    assert distributions.normal_cdf(2.0) == stats.norm.cdf(2.0)
