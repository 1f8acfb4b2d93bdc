"""A TUI profile names exactly the samples it calibrated: the capture runs on after the compute (the operator
still holds the last face), and the certificate's figures are drawn from a re-run on those samples only."""

import asyncio

from accelrig.cli import main
from accelrig.profiles import load_profile
from accelrig.recording import load_recording
from accelrig.tui.app import AccelrigApp
from accelrig.tui.screens.dialogs import PathScreen, SettingsForm
from accelrig.tui.screens.results import ResultsScreen
from tui_support import async_test, wait_for

# the six faces, then +z again and again: never through the drift check's rounds, so the wizard does not compute
# on its own, and hours of device time follow the faces, so the source cannot end (and the wizard compute on its
# own) before the key, even on an idle machine; with a small buffer a pump feeds at most 20 s of them
DEVICE = "sim://static?seed=3&pace=fast&order=+z,-z,+x,-x,+y,-y" + ",+z" * 2000


@async_test
async def test_a_capture_that_runs_on_after_the_compute_still_gives_the_certificate_its_figures(tmp_path, capsys):
    app = AccelrigApp(device=DEVICE, refresh_interval=0.05, profile_dir=tmp_path, buffer_seconds=1.0)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.session is not None)
        await pilot.press("k", "enter")
        await wait_for(pilot, lambda: isinstance(app.screen, SettingsForm))
        await pilot.press("enter")
        wizard = app.screen
        await wait_for(pilot, lambda: wizard.procedure is not None and wizard.procedure.done)
        # computes while the device streams on (the operator still holds the last face): pressed between two
        # pumps (a pump reads and feeds under this lock), with most of the run still to come
        # between two holds (the sensor moving): the live fit and the report's re-run of the first N samples then
        # see the same closed poses (a hold still open at the key is closed by the re-run's end of file, not by
        # the live fit: that case does not reproduce yet, see docs/profiles.md)
        for _ in range(5000):
            await asyncio.to_thread(wizard._lock.acquire)
            if not wizard.procedure.faces["still"]:
                break
            wizard._lock.release()
            await pilot.pause(0.005)
        else:
            raise AssertionError("the sensor never moved between holds")
        try:
            # a pump waits on the lock with what the device delivered since: it feeds after the compute took its
            # samples, as it does when the key lands mid-read (under load; on an idle machine none was waiting)
            await wait_for(pilot, lambda: wizard._pumping)
            await pilot.press("c")
        finally:
            wizard._lock.release()
        await wait_for(pilot, lambda: isinstance(app.screen, ResultsScreen) and app.screen.profile is not None)
        used = app.screen.profile.data["provenance"]["recording_samples"]
        await pilot.press("s")
        await wait_for(pilot, lambda: isinstance(app.screen, PathScreen))
        await pilot.press("enter")
        path = tmp_path / "sim-random-3-static.yaml"
        await wait_for(pilot, path.exists)
        await wait_for(pilot, lambda: wizard.recorder.samples > used)   # the capture ran on after the compute
    capture = load_recording(tmp_path / load_profile(path).data["provenance"]["recording_source"])
    assert len(capture) > used
    capsys.readouterr()
    assert main(["report", str(path), "-o", str(tmp_path / "c.html")]) == 0
    err = capsys.readouterr().err
    # the re-run reads exactly the samples calibrated: their hash is the profile's (before, the whole capture was
    # hashed and re-run, and the figures were dropped without a word)
    assert f"re-running the static calibration on {tmp_path / 'captures'}" in err and f"({used} samples)" in err
    assert "is not the one calibrated" not in err and "hash differs" not in err, err
    # Whether the re-run reproduces the live fit still depends on where the key fell: a hold the live fit saw
    # open is closed by the re-run's end of data (about 1 run in 4 under load; docs/profiles.md).  Whatever
    # happens, a figure left out is said on stderr as in the certificate, never silently.
    page = (tmp_path / "c.html").read_text()
    assert ("figure not shown" in err) == ("Figure not shown" in page), err
