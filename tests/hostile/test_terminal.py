"""Printing what files say safely, and no terminal where one is needed."""

from __future__ import annotations

import subprocess
import sys

import pytest

from accelrig.errors import printable
from accelrig.profiles import load_profile, save_profile
from hostile.support import EXAMPLE_PROFILE, assert_refused

EVIL = "sim\x1b[2J\x1b]0;owned\x07\nline two\r\u202eexe.yaml\x9b31m"


def _no_controls(text: str) -> bool:
    return not any((ord(c) < 32 and c != "\n") or 0x7F <= ord(c) < 0xA0 or 0x202A <= ord(c) <= 0x202E
                   for c in text)


def test_printable_escapes_every_control_character():
    shown = printable(EVIL)
    assert _no_controls(shown) and "\n" not in shown
    assert "\\x1b[2J" in shown and "\\x0a" in shown and "\\u202e" in shown
    assert printable("plain text, 9.81 m/s^2") == "plain text, 9.81 m/s^2"


@pytest.fixture
def evil_store(tmp_path):
    profile = load_profile(EXAMPLE_PROFILE)
    profile.data["device"]["identity"] = EVIL
    profile.data["calibration"]["method"] = "vp\x1b[31m"
    profile.data["warnings"] = ["pose\x1b[1A\x1b[2Kfine"]
    path = tmp_path / "evil.yaml"
    save_profile(profile, path)
    store = tmp_path / "store"
    return path, store


@pytest.mark.parametrize("command", ["list", "show", "show file", "validate", "add"])
def test_profile_commands_never_send_a_files_control_characters(command, cli, evil_store):
    path, store = evil_store
    assert cli("profile", "add", path, "--store", store).returncode == 0
    argv = {"list": ("profile", "list", "--store", store),
            "show": ("profile", "show", EVIL, "--store", store),
            "show file": ("profile", "show", path),
            "validate": ("profile", "validate", path, path),
            "add": ("profile", "add", path, "--store", store)}[command]
    result = cli(*argv)
    assert result.returncode == 0, result.stderr
    assert _no_controls(result.stdout) and _no_controls(result.stderr)
    if command.startswith("show"):
        assert "\\x1b[2J" in result.stdout


def test_an_error_quoting_a_file_escapes_it(guarded, tmp_path):
    path = tmp_path / "rec\x1b[2J.csv"
    path.write_text("t,ax,ay,az\n0,0,0,9.8\n0.1,0,\x1b]0;x\x07,9.8\n")
    result = guarded("calibrate", "static", path)
    assert_refused(result, "is not a number")
    assert "\\x1b[2J" in result.stderr


def test_tui_without_a_terminal_refuses_in_one_line(tmp_path):
    """No terminal on stdin or stdout (a pipe, cron, CI): one line, exit non-zero, at once."""
    proc = subprocess.run([sys.executable, "-m", "accelrig", "tui"], capture_output=True, text=True, timeout=30,
                          stdin=subprocess.DEVNULL, cwd=tmp_path)
    assert_refused(proc, "needs a terminal")
