"""The real `accelrig tui` in a real terminal (tmux): a static calibration with keystrokes alone.

Starts the installed command in a detached tmux session of 80 x 24 on its own
tmux server (so no user session is touched and the test's environment is
used), sends keys, reads the screen with capture-pane, and checks that the
profile file appears and loads.
"""

import os
import shutil
import subprocess
import sys
import time

import pytest

if shutil.which("tmux") is None:
    pytest.skip("tmux is not installed (CI installs it: apt-get install tmux)", allow_module_level=True)

DEVICE = "sim://static?seed=5&pace=fast"


class Tmux:
    def __init__(self, socket: str):
        self.socket = socket

    def run(self, *args, check=True) -> str:
        result = subprocess.run(["tmux", "-L", self.socket, *args], capture_output=True, text=True, timeout=20)
        if check and result.returncode != 0:
            raise AssertionError(f"tmux {' '.join(args)} failed: {result.stderr}")
        return result.stdout

    def screen(self) -> str:
        return self.run("capture-pane", "-p", "-t", "tui", check=False)

    def keys(self, *keys: str) -> None:
        self.run("send-keys", "-t", "tui", *keys)

    def wait_for(self, text: str, timeout: float = 60.0) -> str:
        # (a loaded CI host can take tens of seconds to start the TUI or draw a screen: the timeout is only how
        # long a failure takes to show)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            screen = self.screen()
            if text in screen:
                return screen
            time.sleep(0.1)
        raise AssertionError(f"{text!r} never appeared on the screen; last screen:\n{self.screen()}")


def test_static_calibration_with_keystrokes_alone(tmp_path):
    tmux = Tmux(f"accelrig-test-{os.getpid()}")
    # (Textual draws on stderr, so it is not redirected; an error line stays on the screen)
    command = (f"{sys.executable} -m accelrig tui --device '{DEVICE}' --profile-dir '{tmp_path}'; "
               f"echo exit=$? > '{tmp_path / 'exit.tmp'}' && mv '{tmp_path / 'exit.tmp'}' '{tmp_path / 'exit.txt'}'; sleep 30")
    env_args = [arg for key in ("ACCELRIG_HOME", "XDG_DATA_HOME", "PATH", "HOME") if key in os.environ
                for arg in ("-e", f"{key}={os.environ[key]}")]
    tmux.run("-f", "/dev/null", "new-session", "-d", "-s", "tui", "-x", "80", "-y", "24", *env_args, command)
    try:
        tmux.wait_for("Calibrate")          # the live view's footer
        tmux.wait_for("sim-random-5")       # connected to the simulated device
        tmux.keys("k")
        tmux.wait_for("Static faces")
        time.sleep(0.5)   # as a person would: an enter typed the instant a screen appears can arrive twice
        tmux.keys("Enter")
        tmux.wait_for("enter starts")       # the settings form: the defaults will do
        time.sleep(0.5)
        tmux.keys("Enter")
        tmux.wait_for("Save profile", timeout=120)   # the results screen's footer: all six faces done, fit run
        tmux.keys("s")
        tmux.wait_for("Save the profile to")
        tmux.keys("Enter")
        tmux.wait_for("profile saved")
        tmux.keys("q")
        deadline = time.monotonic() + 60
        while not (tmp_path / "exit.txt").exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert (tmp_path / "exit.txt").read_text().strip() == "exit=0", tmux.screen()
    finally:
        tmux.run("kill-server", check=False)
    profile_path = tmp_path / "sim-random-5-static.yaml"
    assert profile_path.exists(), sorted(p.name for p in tmp_path.iterdir())
    from accelrig.profiles import load_profile

    profile = load_profile(profile_path)
    assert profile.data["calibration"]["procedure"] == "static"
    assert profile.device["identity"] == "sim-random-5"
