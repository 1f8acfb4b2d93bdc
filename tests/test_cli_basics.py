import subprocess
import sys

import pytest

from accelrig import __version__
from accelrig.acquisition.driver import driver_for
from accelrig.acquisition.recorder import record
from accelrig.cli import main
from accelrig.recording import read_csv


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "accelrig", *args], capture_output=True, text=True, timeout=120)


def test_version():
    r = run_cli("--version")
    assert r.returncode == 0
    assert __version__ in r.stdout


def test_record_sim_static_writes_csv(tmp_path):
    out = tmp_path / "x.csv"
    r = run_cli("record", "sim://still?seed=1&pace=fast", "--seconds", "2", "-o", str(out))
    assert r.returncode == 0, r.stderr
    # stdout stays empty; stderr, a pipe here, still says what was kept
    assert r.stdout == "" and r.stderr.count("\n") == 1
    assert r.stderr.startswith("accelrig record: kept ") and f"in {out}; no samples lost" in r.stderr
    lines = [l for l in out.read_text().splitlines() if not l.startswith("#")]
    assert lines[0] == "t,ax,ay,az"
    rec = read_csv(out)
    assert abs(len(rec) - 2 * 200 * 1.004) <= 2
    assert rec.duration < 2.0


def test_record_into_a_pipe_shows_progress_lines_and_says_what_was_lost(tmp_path, monkeypatch, capsys):
    """A piped or logged record is not silent for minutes: whole progress lines, then one summary."""
    import accelrig.commands.record as record_command

    monkeypatch.setattr(record_command, "LOG_PROGRESS_SECONDS", 0.0)   # a line at every progress call
    out = tmp_path / "lossy.csv"
    assert main(["record", "sim://still?seed=4&pace=fast&rate=1000&block=50&drop=0.2", "--seconds", "3",
                 "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert "\r" not in captured.err   # a log gets whole lines, not a line rewritten in place
    progress = [line for line in lines if line.endswith("gaps)")]
    assert progress and all(line.startswith("accelrig record: ") and " Hz  missing " in line for line in progress)
    summary = lines[-1]
    rec = read_csv(out)
    missing = sum(g["missing"] for g in rec.meta["gaps"])
    assert missing > 0
    assert summary.startswith(f"accelrig record: kept {len(rec)} samples (") and f" Hz) in {out}; " in summary
    assert summary.endswith(f"{missing} samples lost in {len(rec.meta['gaps'])} gaps (kept as gaps, never filled in)")


def test_unknown_scheme_one_line_error():
    r = run_cli("record", "bogus://x", "--seconds", "1", "-o", "/tmp/never.csv")
    assert r.returncode != 0
    assert r.stderr.count("\n") == 1
    assert "unknown device URL scheme 'bogus'" in r.stderr
    assert "Traceback" not in r.stderr


def test_broken_csv_row_names_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("t,ax,ay,az\n0,0,0,9.8\n0.005,0,zero,9.8\n")
    r = run_cli("record", f"replay://{bad}?pace=fast", "--samples", "1", "-o", str(tmp_path / "o.csv"))
    assert r.returncode != 0
    assert f"{bad}:3: 'zero' is not a number" in r.stderr
    assert not (tmp_path / "o.csv").exists()


def test_main_returns_exit_code_for_expected_error(capsys, tmp_path):
    code = main(["record", "sim://nosuchrig", "--seconds", "1", "-o", str(tmp_path / "x.csv")])
    assert code != 0
    assert "unknown simulated rig 'nosuchrig'" in capsys.readouterr().err


@pytest.mark.parametrize("module, url, extra", [
    ("serial", "serial:///dev/ttyUSB0", "serial"),
    ("smbus2", "i2c://1/0x68?chip=mpu9250", "i2c"),
    ("bleak", "ble://AA:BB:CC:DD:EE:FF", "ble"),
])
def test_missing_optional_dependency_names_the_extra(monkeypatch, capsys, module, url, extra):
    monkeypatch.setitem(sys.modules, module, None)  # as if the package were not installed
    code = main(["record", url, "--seconds", "1", "-o", "/tmp/never.csv"])
    err = capsys.readouterr().err
    assert code != 0
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"pip install 'accelrig[{extra}]'" in err


def still_csv(path, per_unit: float, digits: int = 6):
    """A still recording written as a plain CSV (no units note) in a unit of ``per_unit`` m/s^2; returns it."""
    with driver_for("sim://still?seed=1&pace=fast") as d:
        rec = record(d, samples=4000)
    path.write_text("t,ax,ay,az\n" + "\n".join(f"{t:.6f}," + ",".join(f"{v / per_unit:.{digits}f}" for v in acc)
                                               for t, acc in zip(rec.t, rec.acc, strict=True)) + "\n")
    return rec


def consumers(path):
    """Every command that reads a recording, with what it needs besides."""
    return (["noise", str(path)],
            ["calibrate", "static", str(path)],
            ["calibrate", "wheel", str(path), "--radius", "0.28"],
            ["verify", "slider-crank", str(path), "--crank-radius", "0.006", "--rod-length", "0.035"])


def test_data_in_g_declared_as_m_s2_is_refused_by_every_consumer(tmp_path, capsys):
    """A file in g without a units note is read as m/s^2: noise, verify and both calibrations refuse it."""
    still_csv(tmp_path / "in_g.csv", 9.80665)
    for args in consumers(tmp_path / "in_g.csv"):
        code = main(args)
        err = capsys.readouterr().err
        assert code != 0, args
        assert "look like g" in err and "--units g" in err and err.count("\n") == 1, (args, err)


def _options_of(args):
    """Every --option the parser of the command ``args`` names defines."""
    from accelrig.cli import build_parser

    parser = build_parser(args)
    action = parser._subparsers._group_actions[0]
    sub = action.choices[args[0]]
    if args[0] in ("calibrate", "verify", "profile"):
        sub = sub._subparsers._group_actions[0].choices[args[1]]
    return {opt for a in sub._actions for opt in a.option_strings}


def test_data_in_milli_g_are_refused_with_options_that_exist_and_read_with_units_mg(tmp_path, capsys):
    """Milli-g read as m/s^2, g or scale-less counts is refused by every consumer; every option its hint names
    exists on that command (the hint once named a scale option none had), and --units mg reads the file."""
    import json
    import re

    import numpy as np

    path = tmp_path / "in_mg.csv"
    still_csv(path, 9.80665e-3, digits=4)
    for args in consumers(path):
        for units in ([], ["--units", "g"], ["--units", "counts"]):
            code = main(args + units)
            err = capsys.readouterr().err
            assert code != 0, args
            assert "look like milli-g" in err and "--units mg" in err and err.count("\n") == 1, (args, err)
            named = set(re.findall(r"--[a-z][a-z-]*", err))
            assert named <= _options_of(args), (args, named - _options_of(args))
    assert main(["noise", str(path), "--units", "mg", "--json"]) == 0
    in_mg = json.loads(capsys.readouterr().out)["axes"]
    still_csv(tmp_path / "si.csv", 1.0)
    assert main(["noise", str(tmp_path / "si.csv"), "--json"]) == 0
    in_si = json.loads(capsys.readouterr().out)["axes"]
    for axis in "xyz":   # mg x 9.80665e-3 is m/s^2: the same densities (to the files' rounding)
        assert np.isclose(in_mg[axis]["density"]["value"], in_si[axis]["density"]["value"], rtol=1e-3), axis


def test_counts_without_a_scale_are_read_with_range_g_on_every_consumer(tmp_path, capsys):
    """The counts hint names --range-g, and every command that reads a recording has it."""
    with driver_for("sim://still?seed=1&pace=fast&range=4") as d:
        rec = record(d, samples=4000)
    scale = rec.meta["scale"]
    path = tmp_path / "counts.csv"
    path.write_text("t,ax,ay,az\n" + "\n".join(f"{t:.6f},{round(a / scale)},{round(b / scale)},{round(c / scale)}"
                                               for t, (a, b, c) in zip(rec.t, rec.acc, strict=True)) + "\n")
    assert main(["noise", str(path), "--units", "counts"]) != 0
    err = capsys.readouterr().err
    assert "--range-g" in err, err
    for args in (["noise"], ["calibrate", "static"], ["calibrate", "wheel"], ["verify", "slider-crank"],
                 ["profile", "apply"]):
        assert {"--units", "--range-g"} <= _options_of(args), args
    assert main(["noise", str(path), "--units", "counts", "--range-g", "4"]) == 0, capsys.readouterr().err


def test_devices_verbose_lists_every_simulator_option_it_accepts(capsys):
    """README sends people to `devices -v` for the simulator's options: each one the URL accepts is there."""
    from accelrig_drivers.sim import SENSOR_OPTIONS

    assert main(["devices", "-v"]) == 0
    out = capsys.readouterr().out
    for option in SENSOR_OPTIONS:
        assert f"        {option}: " in out, option
    driver_for("sim://still?disconnect_after=5&drop=0.1").check_url()   # the listed options are accepted


DRIVER_URLS = ["sim://still", "serial-sim://still", "ble-sim://still", "i2c-sim://mpu9250?rig=still",
               "serial:///dev/ttyUSB0", "ble://AA:BB:CC:DD:EE:FF", "i2c://1/0x68", "replay://run.csv"]


def test_devices_verbose_lists_every_option_of_every_driver(capsys):
    """Each driver's URL options, each with what it does, are in `devices -v`: exactly those its URLs accept
    (besides the rig's own, listed under sim://)."""
    from accelrig.sim.rigs import RIGS

    assert main(["devices", "-v"]) == 0
    lines = capsys.readouterr().out.splitlines()
    for url in DRIVER_URLS:
        driver = driver_for(url)
        listed = set(type(driver).option_help())
        rig = set(RIGS["still"].options) if type(driver).takes_rig_options else set()
        assert listed | rig == driver.known_options(), url
        start = next(i for i, line in enumerate(lines) if line.startswith(f"{driver.scheme}://  "))
        own = []
        for line in lines[start + 1:]:
            if not line.startswith("    "):
                break
            own.append(line)
        for option in listed:
            assert any(line.startswith(f"        {option}: ") and len(line) > len(option) + 12 for line in own), \
                (url, option)


def test_every_help_fits_80_columns_and_says_one_store_default(monkeypatch, capsys):
    """Every command's and kind's --help at 80 columns: no line wider (a choice setting's words made usage lines
    86 wide, collect's 81); the profile store's default reads the same wherever --store is offered."""
    from accelrig.cli import COMMANDS, build_parser

    monkeypatch.setenv("COLUMNS", "80")
    helps = {}
    for name in COMMANDS:
        sub = build_parser([name])._subparsers._group_actions[0].choices[name]
        parsers = {name: sub}
        for action in sub._actions:
            if action.__class__.__name__ == "_SubParsersAction":
                parsers.update({f"{name} {kind}": p for kind, p in action.choices.items()})
        helps.update({key: p.format_help() for key, p in parsers.items()})
    assert len(helps) > 25
    for key, text in helps.items():
        wide = [line for line in text.splitlines() if len(line) > 80]
        assert not wide, (key, wide)
    stores = {" ".join(text.split("\n  --store DIR")[1].split("\n  -", 1)[0].split()) for text in helps.values()
              if "\n  --store DIR" in text}
    assert len(stores) == 1 and "XDG_DATA_HOME" in stores.pop()
