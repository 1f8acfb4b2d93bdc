"""Every wizard from the real `accelrig tui` in tmux, on the device the TUI opens with, to a saved result.

Only what the screen tells the operator is used: the TUI opens on its default device (a simulated
static rig); a wizard of another kind says the device does not fit and offers its simulated rig (the
first choice, with the settings filled in); the result is saved where the TUI offers (the profile
store under ACCELRIG_HOME, or beside it for reports).  No device URL is typed in the TUI.  The static
wizard's test opens the same simulated rig played fast (``accelrig tui --device``, as an operator trying
the TUI may): at the default's own pace its fifteen holds take 90 s of the suite's time.
"""

import os
import shutil
import sys
import time

import pytest
from test_tui_tmux import Tmux

if shutil.which("tmux") is None:
    pytest.skip("tmux is not installed (CI installs it: apt-get install tmux)", allow_module_level=True)


def start_tui(tmp_path, name: str, device: str | None = None) -> Tmux:
    tmux = Tmux(f"accelrig-{name}-{os.getpid()}")
    home = tmp_path / "home"
    option = f" --device '{device}'" if device else ""
    command = f"{sys.executable} -m accelrig tui{option}; echo exit=$? > '{tmp_path / 'exit.tmp'}' && mv '{tmp_path / 'exit.tmp'}' '{tmp_path / 'exit.txt'}'; sleep 30"
    env = {**{k: os.environ[k] for k in ("PATH", "HOME") if k in os.environ}, "ACCELRIG_HOME": str(home)}
    env_args = [arg for key, value in env.items() for arg in ("-e", f"{key}={value}")]
    tmux.run("-f", "/dev/null", "new-session", "-d", "-s", "tui", "-x", "80", "-y", "24", *env_args, command)
    tmux.wait_for("Calibrate")      # the live view's footer
    tmux.wait_for(device or "sim://static")   # the device streams
    return tmux


def choose_wizard(tmux: Tmux, downs: int) -> None:
    tmux.keys("k")
    tmux.wait_for("Choose a calibration")
    time.sleep(0.5)   # as a person would: an enter typed the instant a screen appears can arrive twice
    for _ in range(downs):
        tmux.keys("Down")
    tmux.keys("Enter")


def take_the_simulated_rig(tmux: Tmux, lacks: str) -> None:
    """The default device is of the wrong kind: said, and its simulated rig is the first offer."""
    screen = tmux.wait_for("Use the simulated")
    assert lacks in screen, screen
    time.sleep(0.3)
    tmux.keys("Enter")
    tmux.wait_for("filled in for the simulated rig")
    time.sleep(0.5)
    tmux.keys("Enter")   # the settings as filled in


def save_and_quit(tmux: Tmux, tmp_path, prompt: str, saved: str, timeout: float) -> str:
    tmux.wait_for(prompt, timeout=timeout)
    time.sleep(0.3)
    tmux.keys("s")
    tmux.wait_for("enter saves")
    tmux.keys("Enter")
    screen = tmux.wait_for(saved)
    tmux.keys("q")   # saved: quits without asking
    deadline = time.monotonic() + 60
    while not (tmp_path / "exit.txt").exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert (tmp_path / "exit.txt").read_text().strip() == "exit=0", tmux.screen()
    return screen


def stored_profiles(tmp_path) -> list:
    return sorted((tmp_path / "home" / "profiles").glob("*/*.yaml"))


def test_static_wizard_walks_the_whole_sequence_to_a_profile_in_the_store(tmp_path):
    tmux = start_tui(tmp_path, "static", device="sim://static?pace=fast")
    try:
        choose_wizard(tmux, 0)
        tmux.wait_for("enter starts")   # the settings form: the defaults will do
        time.sleep(0.5)
        tmux.keys("Enter")
        save_and_quit(tmux, tmp_path, "s saves the profile", "profile saved", timeout=120)
    finally:
        tmux.run("kill-server", check=False)
    from accelrig.profiles import load_profile

    (path,) = stored_profiles(tmp_path)
    calibration = load_profile(path).data["calibration"]
    assert calibration["procedure"] == "static"
    # the wizard computed when the sequence was through: six faces, one of each axis again, the opposites, the
    # first ones a third time
    assert calibration["settings"]["faces"] == ["+z", "-z", "+x", "-x", "+y", "-y", "+z", "+x", "+y", "-z", "-x", "-y",
                                                "+z", "+x", "+y"]


def test_wheel_wizard_offers_its_simulated_rig_and_saves_a_profile(tmp_path):
    tmux = start_tui(tmp_path, "wheel")
    try:
        choose_wizard(tmux, 1)
        take_the_simulated_rig(tmux, "lacks rotation")
        save_and_quit(tmux, tmp_path, "s saves the profile", "profile saved", timeout=150)
    finally:
        tmux.run("kill-server", check=False)
    from accelrig.profiles import load_profile

    (path,) = stored_profiles(tmp_path)
    assert load_profile(path).data["calibration"]["procedure"] == "wheel"


def test_slider_crank_wizard_offers_its_simulated_rig_and_saves_the_verification(tmp_path):
    tmux = start_tui(tmp_path, "slider")
    try:
        choose_wizard(tmux, 2)
        take_the_simulated_rig(tmux, "slider-crank")
        save_and_quit(tmux, tmp_path, "slider-crank verification: holds", "verification saved", timeout=120)
    finally:
        tmux.run("kill-server", check=False)
    import yaml

    saved = yaml.safe_load((tmp_path / "home" / "slider-crank-verification.yaml").read_text())
    assert saved["details"]["verdict"] == "holds" and len(saved["details"]["steps"]) == 3


def test_rotary_wizard_offers_its_simulated_bench_and_saves_the_campaign_report(tmp_path):
    tmux = start_tui(tmp_path, "rotary")
    try:
        choose_wizard(tmux, 3)
        take_the_simulated_rig(tmux, "encoder angle")
        for repeat in (1, 2):   # the screen says what to set and to press space when the bench runs steadily
            tmux.wait_for(f"record 2 s (repeat {repeat})")
            time.sleep(0.5)
            tmux.keys("Space")
        save_and_quit(tmux, tmp_path, "campaign report", "report saved", timeout=120)
    finally:
        tmux.run("kill-server", check=False)
    report = (tmp_path / "home" / "rotary-campaign.md").read_text()
    assert report.startswith("# Rotary bench campaign") and "linearity not evaluated" in report
