"""The daemon as a real process on simulated devices, with injected faults and real signals.

For every device: the samples the driver delivered (the daemon's journal, event "stop") equal
the samples in the segment files plus the samples in "disk full" gap records, exactly; the
samples the device reported lost equal the gap records of known size; and consecutive sample
times are one period apart except where a gap record says why.
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from accelrig.recording import read_segments

DEVICE_GAP_CAUSES = ("FIFO overflow", "frames lost on the link", "samples lost by the device")


def start(config: dict, path: Path, env: dict | None = None) -> subprocess.Popen:
    path.write_text(yaml.safe_dump(config))
    log = open(path.with_suffix(".log"), "ab")
    return subprocess.Popen([sys.executable, "-m", "accelrig", "daemon", "--config", str(path)],
                            stdout=log, stderr=log, env={**os.environ, **(env or {})})


def status(config_path: Path) -> dict:
    result = subprocess.run([sys.executable, "-m", "accelrig", "daemon", "status", "--config", str(config_path),
                             "--json"], capture_output=True, text=True, timeout=30)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def status_now(socket: Path) -> dict | None:
    """The same answer as ``status`` through the socket's client in this process: polling with a new
    ``accelrig`` process each time cost about a second of start-up per poll on a loaded 2-core machine."""
    from accelrig.daemon.status import StatusError, query

    try:
        return query(socket)
    except StatusError:
        return None


def wait_until(proc, config_path: Path, condition, timeout: float = 120.0) -> dict:
    # (counted from before the daemon's start-up, which took over 20 s of a loaded 2-core machine: a 30 s wait
    # timed out with the daemon up 7 s.  Only a failing test waits the timeout out.)
    deadline = time.monotonic() + timeout
    last = None
    while time.monotonic() < deadline:
        assert proc.poll() is None, config_path.with_suffix(".log").read_text()
        socket = Path(yaml.safe_load(config_path.read_text())["output"]) / "daemon.sock"
        if socket.exists():
            last = status_now(socket)
            try:
                if last is not None and condition({d["name"]: d for d in last["devices"]}):
                    return last
            except KeyError:   # a device not listed (yet, or any more: a reload adds and removes): not yet
                pass
        time.sleep(0.3)
    raise AssertionError(f"timed out; last status {last}\n{config_path.with_suffix('.log').read_text()}")


def terminate(proc, sig=signal.SIGTERM) -> float:
    """Send ``sig``; the daemon must exit 0 within 5 s.  Returns how long it took."""
    t0 = time.monotonic()
    proc.send_signal(sig)
    rc = proc.wait(timeout=15)
    took = time.monotonic() - t0
    assert rc == 0
    assert took < 5.0, f"the daemon took {took:.1f} s to stop"
    return took


def journal(directory: Path) -> list[dict]:
    return [json.loads(line) for line in (directory / "journal.jsonl").read_text().splitlines()]


def check_accounting(directory: Path, rate: float, slack: float = 0.6) -> tuple[list[dict], dict]:
    """The invariants of the module docstring for one device directory; returns (gaps, summed counts).

    ``slack``: how far (in periods) the step between two samples may stray from one period.
    """
    stops = [e for e in journal(directory) if e["event"] == "stop"]
    assert stops, "the journal has no stop event"
    total = {k: sum(e["counts"][k] for e in stops) for k in ("delivered", "written", "dropped", "missing")}
    rec = read_segments(directory, units="counts")
    gaps = rec.meta["gaps"]
    dropped_in_gaps = sum(g["missing"] for g in gaps if g["cause"] in ("disk full", "write failed"))
    assert total["delivered"] == total["written"] + total["dropped"]
    assert total["written"] == len(rec.t)
    assert total["dropped"] == dropped_in_gaps
    reported = sum(g["missing"] for g in gaps if g["cause"].startswith(DEVICE_GAP_CAUSES) and g["missing"] > 0)
    assert total["missing"] == reported
    # continuity: one period between samples, except where a gap record is
    dt = np.diff(rec.t)
    odd = set((np.flatnonzero(np.abs(dt * rate - 1) > slack) + 1).tolist())
    explained = {g["index"] for g in gaps}
    unexplained = sorted(odd - explained)
    assert not unexplained, ([(i, round(float(dt[i - 1] * rate), 3)) for i in unexplained[:5]], gaps[:5])
    assert np.all(dt > 0)
    return gaps, total


def test_faults_reload_and_term(tmp_path):
    out = tmp_path / "out"
    base = {"output": str(out), "status_interval": 1, "stall_seconds": 1.5, "reconnect_initial": 0.2,
            "reconnect_max": 1}
    devices = [
        {"name": "steady", "url": "sim://still?seed=1&rate=500"},
        {"name": "disc", "url": "sim://still?seed=3&rate=200&disconnect_after=1"},
        {"name": "ser", "url": "serial-sim://still?seed=2&rate=500&corrupt=0.1"},
        {"name": "fifo", "url": "i2c-sim://mpu9250?rig=still&rate=1000&poll=0.084"},
        # its own stall=0.5 is its limit: the serial driver cuts it (the daemon's watch would at 1.5 s), and the
        # gap says "stalled" all the same (it said "disconnected: ... the device stalled", never the documented cause)
        {"name": "stall", "url": "serial-sim://still?seed=4&rate=200&stall_at=1&stall_for=inf&stall=0.5"},
    ]
    config_path = tmp_path / "daemon.yaml"
    proc = start({**base, "devices": devices}, config_path)
    try:
        wait_until(proc, config_path, lambda d: d["disc"]["connects"] >= 2 and d["stall"]["connects"] >= 2
                   and d["ser"]["missing"] > 0 and d["fifo"]["missing"] > 0 and d["steady"]["written"] > 0)
        table = subprocess.run([sys.executable, "-m", "accelrig", "daemon", "status", "--config", str(config_path)],
                               capture_output=True, text=True, timeout=30)
        assert table.returncode == 0 and "steady" in table.stdout and "streaming" in table.stdout
        # reload: stall removed, ser changed, late added, the others unchanged
        changed = [d for d in devices if d["name"] != "stall"]
        changed[2] = {"name": "ser", "url": "serial-sim://still?seed=2&rate=500&corrupt=0.05"}
        changed.append({"name": "late", "url": "sim://still?seed=7&rate=200"})
        config_path.write_text(yaml.safe_dump({**base, "devices": changed}))
        before = {d["name"]: d for d in status(config_path)["devices"]}
        proc.send_signal(signal.SIGHUP)
        after = wait_until(proc, config_path, lambda d: "stall" not in d and "late" in d
                           and d["late"]["written"] > 0 and d["ser"]["url"].endswith("corrupt=0.05")
                           and d["ser"]["written"] > 0)
        after = {d["name"]: d for d in after["devices"]}
        assert after["steady"]["connects"] == 1 and after["steady"]["gaps"] == 0
        assert after["steady"]["written"] > before["steady"]["written"]
        assert after["ser"]["delivered"] < before["ser"]["delivered"]   # a new runner counts afresh
        terminate(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    log = config_path.with_suffix(".log").read_text()
    assert "reloaded" in log and "removed stall;" in log and "restarted ser;" in log

    gaps, _ = check_accounting(out / "steady", 500)
    assert gaps == []   # unchanged by the reload: streamed without a gap
    gaps, _ = check_accounting(out / "disc", 200)
    disconnects = [g for g in gaps if g["cause"].startswith("disconnected")]
    assert disconnects and all(g["seconds"] > 0 for g in disconnects)
    # The simulated firmware's clock runs ~480 ppm from the host's, near the link's 500 ppm limit for
    # host alignment, which a loaded host switches on and off: the times must stay continuous anyway.
    gaps, total = check_accounting(out / "ser", 500)
    assert total["missing"] > 0 and any(g["cause"].startswith("frames lost on the link") for g in gaps)
    assert any(g["cause"] == "not recording: restarted: its configuration changed" for g in gaps)
    gaps, total = check_accounting(out / "fifo", 1000)
    assert total["missing"] > 0 and any(g["cause"].startswith("FIFO overflow") for g in gaps)
    gaps, _ = check_accounting(out / "stall", 200)
    assert any(g["cause"].startswith("stalled: no data for 0.5 s while connected (") for g in gaps)
    assert not any(g["cause"].startswith("disconnected") for g in gaps)
    check_accounting(out / "late", 200)
    stops = [e for e in journal(out / "stall") if e["event"] == "stop"]
    assert stops[-1]["reason"] == "removed from the configuration"
    ser_stops = [e for e in journal(out / "ser") if e["event"] == "stop"]
    assert [e["reason"] for e in ser_stops] == ["restarted: its configuration changed", "the daemon was stopped"]
    assert ser_stops[0]["counts"]["missing"] > 0


def test_kill9_then_restart_recovers_the_open_segment_and_sigint_stops(tmp_path):
    out = tmp_path / "out"
    config = {"output": str(out), "devices": [{"name": "a", "url": "sim://still?seed=1&rate=500"}]}
    config_path = tmp_path / "daemon.yaml"
    proc = start(config, config_path)
    try:
        wait_until(proc, config_path, lambda d: d["a"]["written"] >= 1000)
        proc.kill()
        proc.wait(timeout=10)
        assert list((out / "a").glob("*.seg")), "the open segment is on disk"
        assert (out / "daemon.sock").exists()   # left behind; the next start replaces it
        proc = start(config, config_path)
        wait_until(proc, config_path, lambda d: d["a"]["written"] >= 500)
        terminate(proc, signal.SIGINT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    events = journal(out / "a")
    recovered = [e for e in events if e["event"] == "recovered"]
    assert len(recovered) == 1 and recovered[0]["samples"] >= 1000
    assert not list((out / "a").glob("*.seg"))
    rec = read_segments(out / "a", units="counts")
    stop = [e for e in events if e["event"] == "stop"]
    assert len(stop) == 1   # the killed run never stopped
    # the killed run's samples (what reached the disk) + the second run's, nothing else
    assert len(rec.t) == recovered[0]["samples"] + stop[0]["counts"]["written"]
    gaps = rec.meta["gaps"]
    assert any(g["cause"].startswith("not recording: the previous run ended without stopping") and g["seconds"] > 0
               for g in gaps)
    dt = np.diff(rec.t)
    odd = set((np.flatnonzero(np.abs(dt * 500 - 1) > 0.6) + 1).tolist())
    assert odd <= {g["index"] for g in gaps}


def test_an_unwritable_output_is_refused_in_one_line(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    config_path = tmp_path / "daemon.yaml"
    config_path.write_text(yaml.safe_dump({"output": str(blocker / "out"),
                                           "devices": [{"name": "a", "url": "sim://still"}]}))
    result = subprocess.run([sys.executable, "-m", "accelrig", "daemon", "--config", str(config_path)],
                            capture_output=True, text=True, timeout=30)
    assert result.returncode == 9
    assert result.stderr.count("\n") == 1 and result.stderr.startswith("accelrig: error: output: cannot create")


def _profile_for(tmp_path, identity: str, driver: str, chip: str, who_am_i) -> Path:
    """An example profile (made by profiles/make_examples.py from the simulator) re-addressed to another device."""
    from accelrig.profiles import load_profile, save_profile

    repo = Path(__file__).resolve().parents[1]
    profile = load_profile(repo / "profiles" / "example-static_faces-vp.yaml")
    profile.data["device"].update(identity=identity, driver=driver, chip=chip, who_am_i=who_am_i, url=None)
    path = tmp_path / f"{identity}.yaml"
    save_profile(profile, path)
    return path


def test_calibrated_output_and_offsets_flashed_on_every_connect(tmp_path):
    from accelrig.profiles import load_profile
    from accelrig.units import STANDARD_GRAVITY

    repo = Path(__file__).resolve().parents[1]
    example = repo / "profiles" / "example-static_faces-vp.yaml"    # made for sim seed 11
    chip_profile = _profile_for(tmp_path, "i2c-sim-mpu9250-seed3", "i2c-sim", "mpu9250", 0x71)
    out = tmp_path / "out"
    config = {"output": str(out), "devices": [
        {"name": "cal", "url": "sim://still?seed=11&rate=200", "profile": str(example), "output": "calibrated",
         "uncertainty": True},
        # the chip's cable is pulled 2 s after each connect: the chip loses power and with it the
        # flashed offsets, so the daemon must flash again on reconnecting
        {"name": "chip", "url": "i2c-sim://mpu9250?rig=still&rate=200&seed=3&disconnect_after=2",
         "profile": str(chip_profile), "flash": True, "output": "calibrated"},
    ]}
    config_path = tmp_path / "daemon.yaml"
    proc = start(config, config_path)
    try:
        # one connection delivers at most 400 samples at 200 Hz: 500 needs a reconnect
        wait_until(proc, config_path, lambda d: d["cal"]["written"] >= 400 and d["chip"]["written"] >= 500)
        terminate(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    rec = read_segments(out / "cal")
    cal = np.column_stack([rec.channels[c] for c in ("cal_x", "cal_y", "cal_z")])
    assert abs(np.linalg.norm(cal.mean(axis=0)) - STANDARD_GRAVITY) < 0.02
    assert abs(np.linalg.norm(rec.acc.mean(axis=0)) - STANDARD_GRAVITY) > abs(
        np.linalg.norm(cal.mean(axis=0)) - STANDARD_GRAVITY)   # the correction did something
    assert np.all(rec.channels["u_x"] > 0)
    assert rec.meta["profile"]["path"] == str(example)
    connects = [e for e in journal(out / "chip") if e["event"] == "connect"]
    bias = load_profile(chip_profile).correction.bias
    assert len(connects) >= 2
    for event in connects:
        assert event["flashed"]["verified"] is True
        np.testing.assert_allclose(event["hardware_bias_removed"], bias, atol=0.0097)   # one register step
    check_accounting(out / "chip", 200)
    check_accounting(out / "cal", 200)
    # `profile apply` on the daemon's output: the device is recognised (no "cannot check" warning)
    # and a flashed chip's offsets are not subtracted twice: it gives the daemon's own cal channels
    from accelrig.profiles.apply import apply_profile
    from accelrig.recording import load_recording

    for name, path in (("cal", example), ("chip", chip_profile)):
        raw = load_recording(out / name)
        assert raw.meta["identity"] and raw.meta["chip"]
        applied, warnings = apply_profile(load_profile(path), raw)
        # nothing about the device; only that the recorded calibrated channels are left out (same profile)
        assert len(warnings) == 1 and warnings[0].startswith("the recording held channels cal_x, cal_y, cal_z"), warnings
        assert "that same profile, and equal its cal_x, cal_y, cal_z" in warnings[0]
        assert not any(c in applied.channels for c in ("cal_x", "cal_y", "cal_z", "u_x", "u_y", "u_z"))
        daemon_cal = np.column_stack([raw.channels[c] for c in ("cal_x", "cal_y", "cal_z")])
        np.testing.assert_allclose(applied.acc, daemon_cal, atol=1e-9)


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a tmpfs needs root (CI runs as root)")
def test_disk_full_drops_counted_samples_and_resumes(tmp_path):
    disk = tmp_path / "disk"
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(disk)], capture_output=True)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    try:
        out = disk / "out"
        config = {"output": str(out), "segment_seconds": 2,
                  "devices": [{"name": "a", "url": "sim://still?seed=1&rate=2000"}]}
        config_path = tmp_path / "daemon.yaml"
        proc = start(config, config_path)
        try:
            wait_until(proc, config_path, lambda d: d["a"]["written"] >= 2000)
            filler = disk / "filler"
            with open(filler, "wb") as fh:   # fill the disk to the brim
                try:
                    while True:
                        fh.write(b"\0" * 65536)
                        fh.flush()
                except OSError:
                    pass
            full = wait_until(proc, config_path, lambda d: d["a"]["dropped"] > 0)
            assert {d["name"]: d for d in full["devices"]}["a"]["state"] == "disk full"
            # full across two retries (DISK_RETRY 2 s): a retry that finds no room is not a recovery
            # (a gap record fits in the open segment's last page where a data block does not)
            time.sleep(4.5)
            still = {d["name"]: d for d in status(config_path)["devices"]}["a"]
            assert still["state"] == "disk full" and still["gaps"] == 0, still
            assert "writing again" not in config_path.with_suffix(".log").read_text()
            filler.unlink()   # space returns
            wait_until(proc, config_path, lambda d: d["a"]["state"] == "streaming" and d["a"]["gaps"] >= 1)
            terminate(proc)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=10)
        gaps, total = check_accounting(out / "a", 2000)
        assert total["dropped"] > 0
        assert [g["missing"] for g in gaps if g["cause"] == "disk full"] == [total["dropped"]]
    finally:
        # a lazy unmount when the plain one finds the tmpfs busy (a file still open in a dying
        # process), so no mount outlives the test and pytest can remove its folder
        if subprocess.run(["umount", str(disk)], capture_output=True).returncode != 0:
            subprocess.run(["umount", "-l", str(disk)], capture_output=True)


def test_systemd_notify_watchdog_metrics_and_the_tui_screen(tmp_path):
    import socket
    import urllib.request

    from accelrig.tui.app import AccelrigApp
    from tui_support import async_test, wait_for

    notify_path = tmp_path / "notify"
    receiver = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    receiver.bind(str(notify_path))
    receiver.settimeout(0.2)
    from mqtt_support import free_port

    # free now, and below the ephemeral range: no outgoing connection of another test is handed it before the
    # daemon binds it (a port the kernel picked with bind(0) is in that range)
    port = free_port()
    out = tmp_path / "out"
    config = {"output": str(out), "metrics_port": port,
              "devices": [{"name": "a", "url": "sim://still?seed=1&rate=200"},
                          {"name": "gone", "url": "serial:///dev/nonexistent-accelrig-test"}]}
    config_path = tmp_path / "daemon.yaml"
    proc = start(config, config_path, env={"NOTIFY_SOCKET": str(notify_path), "WATCHDOG_USEC": "1000000"})
    messages = []
    try:
        wait_until(proc, config_path, lambda d: d["a"]["written"] > 0 and d["gone"]["failed_connects"] >= 2)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and sum("WATCHDOG=1" in m for m in messages) < 2:
            try:
                messages.append(receiver.recv(4096).decode())
            except TimeoutError:
                pass
        text = urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10).read().decode()

        @async_test
        async def screen():
            app = AccelrigApp(daemon_socket=out / "daemon.sock")
            async with app.run_test(size=(120, 30)) as pilot:
                from textual.widgets import DataTable

                await wait_for(pilot, lambda: app.screen.query_one(DataTable).row_count == 2)
                table = app.screen.query_one(DataTable)
                return [table.get_row_at(i)[:2] for i in range(2)]

        rows = screen()
        terminate(proc)
    finally:
        receiver.close()
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    assert messages[0].startswith("READY=1\nSTATUS=")   # READY although one device is missing
    assert any(m.startswith("WATCHDOG=1") for m in messages)
    assert 'accelrig_samples_written_total{device="a"}' in text
    assert 'accelrig_device_up{device="gone",state="waiting"} 0.0' in text
    assert rows == [["a", "streaming"], ["gone", "waiting"]]
    waits = [e["retry_in"] for e in journal(out / "gone") if e["event"] == "connect_failed"]
    assert len(waits) >= 2 and waits == [min(2.0 ** i, 60) for i in range(len(waits))]   # exponential backoff
    assert [e["event"] for e in journal(out / "gone")][-1] == "stop"


# The daemon with one device ("pier") whose start takes long (as a long recovery of a crashed run's segment
# would): the same program, started through this wrapper so the delay lands exactly there.  It lasts until the
# test has read the status socket's first answer and creates the file PIER_GO (a fixed second could be over
# before a loaded machine let the test ask).
SLOW_START = """
import os, sys, time
from accelrig.daemon import device
from accelrig.cli import main
start = device.DeviceRunner.start
def slow_start(self, *args, **kwargs):
    if self.device.name == "pier":
        deadline = time.monotonic() + 120
        while not os.path.exists(os.environ["PIER_GO"]) and time.monotonic() < deadline:
            time.sleep(0.02)
    start(self, *args, **kwargs)
device.DeviceRunner.start = slow_start
sys.exit(main(sys.argv[1:]))
"""


def first_status(proc, config_path: Path, timeout: float = 120.0) -> dict:
    """The status socket's first answer, asked for as soon as the socket is there."""
    socket = Path(yaml.safe_load(config_path.read_text())["output"]) / "daemon.sock"
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, config_path.with_suffix(".log").read_text()
        answer = status_now(socket) if socket.exists() else None
        if answer is not None:
            return answer
        time.sleep(0.02)
    raise AssertionError("the status socket never answered")


def test_a_device_without_the_profile_it_needs_records_raw_loudly_and_takes_the_profile_on_reload(tmp_path):
    """output calibrated, an empty store: the raw counts are recorded anyway and every place says why; the
    profile filed and SIGHUP, the device restarts calibrated; `profile apply` calibrates the raw stretch.
    And the status socket lists every configured device from its first answer, while one takes long to start."""
    from accelrig.daemon.status import format_table
    from accelrig.profiles import load_profile
    from accelrig.profiles.apply import apply_profile
    from accelrig.profiles.store import ProfileStore
    from accelrig.recording import load_recording
    from accelrig.segments import read_arrays, segment_files
    from accelrig.units import STANDARD_GRAVITY

    example = Path(__file__).resolve().parents[1] / "profiles" / "example-static_faces-vp.yaml"  # sim seed 11
    out, store = tmp_path / "out", tmp_path / "store"
    config = {"output": str(out), "profile_store": str(store), "status_interval": 0, "devices": [
        {"name": "pier", "url": "sim://still?seed=11&rate=200", "output": "calibrated"},
        {"name": "strict", "url": "sim://still?seed=11&rate=200", "output": "calibrated",
         "without_profile": "stop"},
        {"name": "chip", "url": "i2c-sim://mpu9250?rig=still&rate=200&seed=3", "flash": True}]}
    config_path = tmp_path / "daemon.yaml"
    config_path.write_text(yaml.safe_dump(config))
    log = open(config_path.with_suffix(".log"), "ab")
    proc = subprocess.Popen([sys.executable, "-c", SLOW_START, "daemon", "--config", str(config_path)],
                            stdout=log, stderr=log, env={**os.environ, "PIER_GO": str(tmp_path / "pier-go")})
    try:
        first = first_status(proc, config_path)   # while pier takes long to start: strict is listed too
        assert [(d["name"], d["state"]) for d in first["devices"]] == [
            ("pier", "starting"), ("strict", "starting"), ("chip", "starting")]
        (tmp_path / "pier-go").touch()   # pier's start goes on
        raw = wait_until(proc, config_path, lambda d: d["pier"]["written"] >= 100 and d["strict"]["state"] == "failed"
                         and d["chip"]["written"] > 0)
        pier, chip = ({d["name"]: d for d in raw["devices"]}[name] for name in ("pier", "chip"))
        assert chip["state"] == "recording raw" and chip["error"].endswith(
            "then reload the daemon (SIGHUP or systemctl reload) to flash its offsets; `accelrig profile apply` "
            "calibrates what was recorded raw")
        assert pier["state"] == "recording raw" and pier["profile"] == "none"
        assert "no profile for 'sim-random-11' in the store" in pier["error"] and "reload" in pier["error"]
        table = format_table(raw)   # what `daemon status` prints (test_faults_reload_and_term runs the command)
        assert "recording raw" in table and "pier: recording raw: no profile for 'sim-random-11'" in table
        proc.send_signal(signal.SIGHUP)   # nothing filed yet: pier keeps recording, untouched
        deadline = time.monotonic() + 60
        while "pier: still recording raw" not in config_path.with_suffix(".log").read_text():
            assert time.monotonic() < deadline, config_path.with_suffix(".log").read_text()
            time.sleep(0.1)
        ProfileStore(store).add(load_profile(example))
        proc.send_signal(signal.SIGHUP)
        wait_until(proc, config_path, lambda d: d["pier"]["state"] == "streaming" and d["pier"]["written"] >= 100)
        terminate(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
    log = config_path.with_suffix(".log").read_text()
    assert "pier: WARNING: recording raw: no profile for 'sim-random-11'" in log
    assert "restarted with the profile they lacked: pier" in log
    assert "strict: stopped: devices[1].profile: no profile for 'sim-random-11'" in log
    assert [e["event"] for e in journal(out / "pier")].count("recording_raw") == 1
    chip_connect = next(e for e in journal(out / "chip") if e["event"] == "connect")
    assert chip_connect["flashed"] is None and chip_connect["hardware_bias_removed"] is None   # factory offsets
    gaps, _ = check_accounting(out / "pier", 200)
    assert [g["cause"] for g in gaps] == ["not recording: restarted: the profile it lacked is there now"]
    rec = load_recording(out / "pier")   # the raw stretch and the calibrated one, read as one
    first_calibrated = gaps[0]["index"]
    assert np.isnan(rec.channels["cal_x"][:first_calibrated]).all()
    assert not np.isnan(rec.channels["cal_x"][first_calibrated:]).any()
    first_meta = read_arrays(segment_files(out / "pier")[0])[4]
    assert first_meta["recording_raw"].startswith("recording raw: no profile for") and first_meta["profile"] is None
    applied, warnings = apply_profile(load_profile(example), rec)
    assert len(warnings) == 1 and "cal_x, cal_y, cal_z, calibrated while it was recorded" in warnings[0], warnings
    daemon_cal = np.column_stack([rec.channels[c] for c in ("cal_x", "cal_y", "cal_z")])
    np.testing.assert_allclose(applied.acc[first_calibrated:], daemon_cal[first_calibrated:], atol=1e-9)
    assert abs(np.linalg.norm(applied.acc[:first_calibrated].mean(axis=0)) - STANDARD_GRAVITY) < 0.02

