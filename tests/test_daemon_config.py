"""The daemon's configuration, status socket and systemd notifications, without running a daemon."""

import json
import os
import socket
import stat
import subprocess
import sys
import threading
from pathlib import Path

import jsonschema
import pytest
import yaml

from accelrig.daemon.config import ConfigError, check_config, json_schema, load_config, parse_config
from accelrig.daemon.notify import notify, watchdog_interval
from accelrig.daemon.status import StatusError, StatusServer, format_table, query

REPO = Path(__file__).resolve().parents[1]
MINIMAL = {"output": "/var/lib/accelrig", "devices": [{"url": "sim://still?seed=1", "name": "bench-a"}]}


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "accelrig", *args], capture_output=True, text=True, timeout=60,
                          cwd=cwd)


def test_the_minimal_config_works_with_every_default():
    config = parse_config(json.loads(json.dumps(MINIMAL)))
    (device,) = config.devices
    assert (device.name, device.url, device.profile, device.output, device.flash) == (
        "bench-a", "sim://still?seed=1", "store", "raw", False)
    assert config.output == Path("/var/lib/accelrig")
    assert config.status_socket == Path("/var/lib/accelrig/daemon.sock")
    assert config.segment_seconds == 3600 and config.stall_seconds == 10
    assert config.reconnect_initial == 1 and config.reconnect_max == 60


@pytest.mark.parametrize(("change", "words"), [
    (lambda c: c.pop("output"), "output: missing (required field)"),
    (lambda c: c["devices"][0].pop("name"), "devices[0].name: missing"),
    (lambda c: c["devices"][0].update(flash="maybe"), "devices[0].flash: expected true or false"),
    (lambda c: c["devices"][0].update(output="both"), "devices[0].output: expected one of 'raw', 'calibrated'"),
    (lambda c: c["devices"][0].update(colour="red"), "devices[0].colour: unknown key"),
    (lambda c: c.update(stall_seconds=0), "stall_seconds: expected a number > 0"),
    (lambda c: c.update(devices=[]), "devices: the list is empty"),
    (lambda c: c["devices"].append({"url": "sim://still", "name": "bench-a"}),
     "devices[1].name: 'bench-a' is already the name of devices[0]"),
    (lambda c: c["devices"][0].update(name="a b"), "devices[0].name: 'a b' does not match"),
    (lambda c: c["devices"][0].update(output="calibrated", profile="none"),
     "devices[0].output: calibrated output needs a profile"),
    (lambda c: c["devices"][0].update(flash=True, profile="none"), "devices[0].flash: flashing needs a profile"),
    (lambda c: c["devices"][0].update(uncertainty=True), "devices[0].uncertainty: uncertainties come with"),
    (lambda c: c.update(reconnect_initial=100), "reconnect_initial: 100 s is longer than reconnect_max"),
])
def test_a_bad_config_is_refused_naming_the_field(change, words):
    config = json.loads(json.dumps(MINIMAL))
    change(config)
    with pytest.raises(ConfigError) as err:
        parse_config(config, "d.yaml")
    assert str(err.value).startswith("d.yaml: ")
    assert words in str(err.value)
    assert "\n" not in str(err.value)


def test_check_names_the_field_of_an_unknown_scheme_a_bad_profile_and_an_unwritable_output(tmp_path):
    bad_scheme = {**MINIMAL, "output": str(tmp_path / "out"),
                  "devices": [{"url": "nosuch://x", "name": "a"}]}
    with pytest.raises(ConfigError, match=r"devices\[0\]\.url: unknown device URL scheme 'nosuch'"):
        check_config(parse_config(bad_scheme))
    (tmp_path / "p.yaml").write_text("schema_version: 1\n")
    bad_profile = {**MINIMAL, "output": str(tmp_path / "out"),
                   "devices": [{"url": "sim://still", "name": "a", "profile": str(tmp_path / "p.yaml")}]}
    with pytest.raises(ConfigError, match=r"devices\[0\]\.profile: .*p\.yaml"):
        check_config(parse_config(bad_profile))
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(ConfigError, match=r"^output: cannot create .*file/out"):
        check_config(parse_config({**MINIMAL, "output": str(blocker / "out")}))


def test_daemon_check_cli_says_valid_or_one_line(tmp_path):
    good = tmp_path / "d.yaml"
    good.write_text(yaml.safe_dump({**MINIMAL, "output": "out"}))
    result = cli("daemon", "check", str(good))
    assert result.returncode == 0, result.stderr
    assert "valid: 1 device(s) (bench-a)" in result.stdout
    assert (tmp_path / "out").is_dir()   # relative to the file, not the working directory
    bad = tmp_path / "bad.yaml"
    bad.write_text("output: out\ndevices:\n  - url: sim://still\n    name: a\n    flash: maybe\n")
    result = cli("daemon", "check", str(bad))
    assert result.returncode == 9
    assert result.stderr.strip().count("\n") == 0
    assert "devices[0].flash" in result.stderr
    result = cli("daemon", "check", str(tmp_path / "none.yaml"))
    assert result.returncode == 9 and "no such file" in result.stderr


@pytest.mark.parametrize("url, option", [("sim://still?sed=1", "sed"), ("serial-sim://still?corupt=0.1", "corupt"),
                                         ("i2c-sim://mpu9250?rig=still&rat=1000", "rat"),
                                         ("ble-sim://still?reorder=0.1&outtage=2", "outtage"),
                                         ("serial:///dev/ttyACM0?bauds=9600", "bauds")])
def test_a_mistyped_url_option_is_refused_by_check_and_at_start_in_one_line(tmp_path, url, option):
    # a typo is not a device that does not answer: refused, naming the device and the option, never retried
    path = tmp_path / "d.yaml"
    path.write_text(yaml.safe_dump({"output": "out", "devices": [{"url": "sim://still", "name": "ok"},
                                                                 {"url": url, "name": "typo"}]}))
    for command in (["daemon", "check", str(path)], ["daemon", "--config", str(path)]):
        result = cli(*command)
        assert result.returncode == 9, result.stderr
        assert result.stderr.count("\n") == 1
        assert "devices[1].url" in result.stderr and f"unknown option(s) {option}" in result.stderr
        assert "'typo'" in result.stderr
    assert not (tmp_path / "out" / "ok").exists()   # nothing started


def test_committed_schema_is_the_generated_one_and_agrees_with_the_validator():
    committed = json.loads((REPO / "profiles" / "daemon-config-v1.json").read_text())
    assert committed == json_schema(), "regenerate with: python profiles/make_examples.py --schema-only"
    validator = jsonschema.Draft202012Validator(committed)
    validator.validate(MINIMAL)
    full = {**MINIMAL, "status_interval": 5, "segment_seconds": 60, "segment_megabytes": 10, "stall_seconds": 3,
            "reconnect_initial": 0.5, "reconnect_max": 30, "profile_store": "/p", "metrics_port": 9108,
            "status_socket": "/run/accelrig/status.sock",
            "devices": [{"url": "sim://still", "name": "a", "profile": "store", "output": "calibrated",
                         "uncertainty": True, "flash": True, "csv": False}]}
    validator.validate(full)
    parse_config(full)
    for broken in ({"devices": MINIMAL["devices"]}, {**MINIMAL, "devices": []}, {**MINIMAL, "extra": 1},
                   {**MINIMAL, "devices": [{"url": "sim://still", "name": "a", "flash": "yes"}]}):
        assert list(validator.iter_errors(broken)), broken
        with pytest.raises(ConfigError):
            parse_config(json.loads(json.dumps(broken)))


def test_status_socket_is_owner_only_and_answers_json(tmp_path):
    path = tmp_path / "s.sock"
    server = StatusServer(path, lambda: {"daemon": {"pid": 1, "uptime": 2.0, "config": "c", "output": "o"},
                                         "devices": [{"name": "a", "state": "streaming", "delivered_rate": 200.0,
                                                      "delivered": 10, "written": 10, "dropped": 0, "missing": 0,
                                                      "gaps": 0, "connects": 1, "bytes_written": 1e6,
                                                      "profile": "none", "error": None}]})
    server.start()
    try:
        assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
        status = query(path)
        assert status["devices"][0]["delivered"] == 10
        table = format_table(status)
        assert table.splitlines()[2].split()[:3] == ["a", "streaming", "200.0"]
        with pytest.raises(ConfigError, match="another daemon answers"):
            StatusServer(path, dict).start()
    finally:
        server.stop()
    assert not path.exists()
    with pytest.raises(StatusError, match="is the daemon running"):
        query(path)


def test_daemon_status_table_fits_80_columns_and_keeps_every_column():
    """`accelrig daemon status` at 80 columns: no line wider (it was about 150), and every device's every
    cell is still printed, the columns that do not fit stacked under the first table, each led by the device."""
    from accelrig.daemon.status import COLUMNS, device_row

    devices = [{"name": name, "state": "recording raw", "delivered_rate": 2048.0, "delivered": 123456789,
                "written": 123456700, "dropped": 89, "missing": 4321, "gaps": 17, "connects": 3,
                "bytes_written": 2.5e9, "profile": f"/home/operator/.local/share/accelrig/profiles/{name}.yaml",
                "error": "recording raw: no profile for 'sim-random-11' in the store: calibrate the device and "
                         "file its profile (accelrig profile add PROFILE), then reload the daemon"}
               for name in ("roof-north-accelerometer", "b")]
    status = {"daemon": {"pid": 4242, "uptime": 86400.0, "config": "/etc/accelrig/a-long-daemon-config-name.yaml",
                         "output": "/srv/accelrig/recordings/site-with-a-long-name"}, "devices": devices}
    table = format_table(status)
    assert max(len(line) for line in table.splitlines()) <= 80, table
    parts = [part.splitlines() for part in table.split("\n\n")]
    titles = [title for _, title in COLUMNS]
    seen = set()
    for part in parts:
        header = next(line for line in part if line.startswith("device"))
        seen |= {title for title in titles if f"  {title}" in f"  {header}"}
    assert seen == set(titles), seen
    for d in devices:
        row = device_row(d)
        lines = [line for line in table.splitlines() if line.startswith(d["name"] + " ")]
        assert len(lines) == len(parts), lines   # each part leads with the device
        assert all(row[key] in " ".join(lines).split() for key, _ in COLUMNS
                   if key not in ("name", "state", "profile")), lines
        assert f"{d['name']}.yaml" in " ".join(lines).split() and d["profile"] in table.split()   # its path under
    assert "roof-north-accelerometer: recording raw: no profile for 'sim-random-11'" in table


def test_notify_sends_datagrams_to_notify_socket_and_reads_the_watchdog(tmp_path, monkeypatch):
    assert notify("READY=1") is False or "NOTIFY_SOCKET" in os.environ
    path = tmp_path / "notify"
    receiver = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    receiver.bind(str(path))
    receiver.settimeout(2)
    got = []
    thread = threading.Thread(target=lambda: got.append(receiver.recv(4096)))
    thread.start()
    monkeypatch.setenv("NOTIFY_SOCKET", str(path))
    assert notify("READY=1\nSTATUS=ok")
    thread.join(3)
    receiver.close()
    assert got == [b"READY=1\nSTATUS=ok"]
    monkeypatch.setenv("WATCHDOG_USEC", "4000000")
    monkeypatch.setenv("WATCHDOG_PID", str(os.getpid()))
    assert watchdog_interval() == 2.0
    monkeypatch.setenv("WATCHDOG_PID", "1")   # meant for another process
    assert watchdog_interval() is None


def test_load_config_reads_yaml_booleans_and_relative_paths(tmp_path):
    path = tmp_path / "d.yaml"
    path.write_text("output: data\nstatus_socket: run/s.sock\ndevices:\n"
                    "  - {url: 'sim://still', name: a, profile: p.yaml, output: calibrated, flash: yes}\n")
    config = load_config(path)
    assert config.output == tmp_path / "data"
    assert config.status_socket == tmp_path / "run" / "s.sock"
    assert config.devices[0].profile == str(tmp_path / "p.yaml") and config.devices[0].flash is True


def test_utc_clock_keeps_time_increasing_measures_the_rate_and_slews_to_the_host(monkeypatch):
    import numpy as np

    from accelrig.daemon import clock as clock_module

    host = {"mono": 100.0}
    monkeypatch.setattr(clock_module.time, "time", lambda: 1.7e9 + host["mono"] - 100.0)
    monkeypatch.setattr(clock_module.time, "monotonic", lambda: host["mono"])
    rate, true_rate = 1000.0, 1000.0 * (1 + 300e-6)   # the device runs 300 ppm fast of the host
    clock = clock_module.UtcClock(rate)
    out = []
    k = 0
    for block in range(400):   # 40 s of 100-sample blocks
        t = (k + np.arange(100)) / rate                 # the driver's device time (nominal rate)
        if block >= 200:
            t = t - 0.004                               # its time base steps 4 ms back once
        k += 100
        host["mono"] = 100.0 + k / true_rate + 0.002    # arrival: after the block's last sample
        out.append(clock.map(t, host["mono"]))
    utc = np.concatenate(out)
    steps = np.diff(utc)
    assert np.all(steps > 0)
    assert clock.steps_back == 1 and abs(clock.largest_step_back - 0.0035) < 1e-9   # -3 ms step vs half a period
    assert abs(clock.measured_rate - true_rate) < 0.05
    assert abs(clock.ratio - 1 / (1 + 300e-6)) < 20e-6
    # host-anchored: the last sample within a few ms of its arrival time, despite 12 ms of drift and the step
    assert abs(utc[-1] - (1.7e9 + host["mono"] - 100.0)) < 0.005


def test_utc_clock_counts_a_gap_an_empty_block_carries(monkeypatch):
    """A gap on an empty block (a stream that ended with a loss, or a replayed gap among others at one place)
    counts as one on the next block does: the same UTC times and the same measured rate follow."""
    import numpy as np

    from accelrig.daemon import clock as clock_module

    host = {"mono": 100.0}
    monkeypatch.setattr(clock_module.time, "time", lambda: 1.7e9 + host["mono"] - 100.0)
    monkeypatch.setattr(clock_module.time, "monotonic", lambda: host["mono"])
    rate = 100.0
    utc, measured = {}, {}
    for empty in (False, True):
        clock, out = clock_module.UtcClock(rate, min_span=1.0), []
        for block in range(60):
            first = 100 * block + (50 if block >= 30 else 0)    # 50 samples lost before block 30
            if block == 30 and empty:
                clock.map(np.empty(0), 100.0 + first / rate, 50)
            t = (first + np.arange(100)) / rate
            out.append(clock.map(t, 100.0 + (first + 100) / rate, 50 if block == 30 and not empty else 0))
        utc[empty], measured[empty] = np.concatenate(out), clock.measured_rate
    np.testing.assert_array_equal(utc[True], utc[False])
    assert measured[True] == measured[False] == pytest.approx(rate, rel=1e-9)


def test_a_reload_with_a_broken_config_keeps_the_running_one(tmp_path, capsys):
    from accelrig.daemon.service import Daemon

    path = tmp_path / "d.yaml"
    path.write_text(yaml.safe_dump({"output": "out", "devices": [{"url": "sim://still", "name": "a"}]}))
    daemon = Daemon(path)
    path.write_text("output: out\ndevices:\n  - {url: 'sim://still', name: a, output: both}\n")
    daemon.reload()
    assert "reload refused, the running configuration is kept" in capsys.readouterr().err
    assert daemon.config.devices[0].output == "raw" and daemon.reloads == 0


def test_check_says_an_empty_store_leaves_a_calibrated_device_recording_raw_or_nothing(tmp_path):
    config = {**MINIMAL, "output": str(tmp_path / "out"), "profile_store": str(tmp_path / "store"),
              "devices": [{"url": "sim://still", "name": "pier", "profile": "store", "output": "calibrated"},
                          {"url": "i2c-sim://mpu9250?rig=still", "name": "strict", "flash": True,
                           "without_profile": "stop"},
                          {"url": "sim://still", "name": "raw", "profile": "store"}]}
    notes = check_config(parse_config(config))
    pier = next(n for n in notes if n.startswith("pier:"))
    assert "output calibrated needs one" in pier and "no profile at all" in pier
    assert "records raw counts only, in state 'recording raw'" in pier
    strict = next(n for n in notes if n.startswith("strict:"))
    assert "flash needs one" in strict and "records nothing (without_profile: stop)" in strict
    raw = next(n for n in notes if n.startswith("raw:"))
    assert "records" not in raw


def test_a_disk_full_gap_record_the_segment_refuses_is_written_before_the_next_block(tmp_path, monkeypatch):
    """Writing resumes with a block, but the gap record after it fails: it is retried, at its own time."""
    import numpy as np

    from accelrig.daemon import device as daemon_device
    from accelrig.errors import StorageFull

    monkeypatch.setattr(daemon_device, "DISK_RETRY", 0.0)
    config = parse_config({**MINIMAL, "output": str(tmp_path), "devices": [{"name": "a", "url": "sim://still"}]})
    runner = daemon_device.DeviceRunner(config.devices[0], config, lambda line: None)
    runner.directory.mkdir()

    class Writer:
        full, gap_failures, gaps, samples = True, 0, [], 0

        def write(self, t, counts, channels):
            if self.full:
                raise StorageFull("the disk is full")
            self.samples += len(counts)

        def gap(self, t, samples, cause, seconds=None):
            if self.gap_failures:
                self.gap_failures -= 1
                raise StorageFull("the disk is full")
            self.gaps.append((t, samples, cause))

    runner.writer = writer = Writer()

    def block(start):
        return np.arange(start, start + 10, dtype=np.int64) * 5_000_000 + 10**18, np.zeros((10, 3), np.int16)

    runner.write(*block(0), None)         # dropped: the disk is full
    writer.full, writer.gap_failures = False, 1
    runner.write(*block(10), None)        # the block goes in, its gap record does not
    assert writer.samples == 10 and writer.gaps == [] and runner.counts.gaps == 0
    runner.write(*block(20), None)        # the record is retried first, placed at the first dropped sample
    assert writer.gaps == [(pytest.approx(1e9), 10, "disk full")] and runner.counts.gaps == 1
    assert runner.counts.dropped == 10 and runner.counts.written == 20


def test_check_refuses_a_profile_made_for_another_chip_than_the_url_names(tmp_path):
    # a sim:// device is chip "sim", i2c-sim://CHIP and i2c://...?chip=CHIP name theirs: a profile for another
    # chip would leave the device recording without it, so check says so before the deployment starts
    from accelrig.profiles import load_profile, save_profile

    example = REPO / "profiles" / "example-static_faces-vp.yaml"   # made on sim://, chip "sim"
    chip = load_profile(example)
    chip.data["device"].update(identity="i2c-sim-mpu9250-seed3", driver="i2c-sim", chip="mpu9250", who_am_i=0x71)
    save_profile(chip, tmp_path / "chip.yaml")

    def config(url, profile):
        return parse_config({"output": str(tmp_path / "out"),
                             "devices": [{"url": "sim://still", "name": "ok"},
                                         {"url": url, "name": "pier", "profile": str(profile)}]})

    for url, profile, made_for, named in (("sim://still?seed=11", tmp_path / "chip.yaml", "mpu9250", "sim"),
                                          ("i2c-sim://mpu9250?rig=still", example, "sim", "mpu9250"),
                                          ("i2c://1/0x68?chip=icm20948", tmp_path / "chip.yaml", "mpu9250", "icm20948")):
        with pytest.raises(ConfigError) as err:
            check_config(config(url, profile))
        assert str(err.value).startswith(f"devices[1].profile: {profile} was made for chip {made_for!r}, but the "
                                          f"device at {url} is chip {named!r} (device 'pier')"), str(err.value)
    # a URL's own profile=PATH is compared the same way
    with pytest.raises(ConfigError, match=r"devices\[1\]\.url: profile=.*chip\.yaml was made for chip 'mpu9250'.* "
                                          r"is chip 'icm20948'"):
        check_config(parse_config({"output": str(tmp_path / "out"), "devices": [
            {"url": "sim://still", "name": "ok"},
            {"url": f"i2c://1/0x68?chip=icm20948&profile={tmp_path / 'chip.yaml'}", "name": "pier"}]}))
    # the chips agree: valid (serial devices say their chip only when they answer)
    check_config(config("sim://still?seed=11", example))
    check_config(config("i2c-sim://mpu9250?rig=still", tmp_path / "chip.yaml"))
    check_config(config("serial:///dev/ttyUSB0", tmp_path / "chip.yaml"))


def test_fitted_lines_keep_every_cell_and_the_width():
    """The one column rule: a table that fits stays one table; one that does not is stacked, each part led by
    the name, every cell printed once, no line wider than asked unless a cell alone is; a lone column prints."""
    from accelrig.tables import fitted_lines

    assert fitted_lines(["a", "b"], [["x", "y"]], [0, 1]) == ["a  b", "x  y"]
    assert fitted_lines(["name"], [["n"]], [0]) == ["name", "n"]
    titles, row = ["name", "c1", "c2", "c3"], ["n", "x" * 30, "y" * 30, "z" * 30]
    lines = fitted_lines(titles, [row], [0, 3, 1, 2], width=50)
    assert lines == ["name  c3", "n     " + "z" * 30, "", "name  c1", "n     " + "x" * 30, "",   # in order of rank
                     "name  c2", "n     " + "y" * 30]
    assert max(map(len, lines)) <= 50 and all(row[i] in " ".join(lines) for i in range(4))


def test_can_flash_is_one_test_for_the_daemon_check_the_tui_and_wrapped_drivers():
    """Driver.can_flash: the driver writes a calibration, and an open device does not say it cannot.  The daemon's
    UtcDriver forwards it (a class comparison took any wrapper for a flashing driver); the TUI asks the same."""
    from accelrig.acquisition.driver import driver_for
    from accelrig.daemon.device import UtcDriver
    from accelrig.tui.screens.results import can_flash

    class Connected:   # what the TUI holds: a session with a driver and its info
        def __init__(self, driver):
            self.driver, self.info = driver, driver.info

    for url, expected in (("sim://still", False), ("i2c-sim://mpu9250?rig=still", True),
                          ("serial-sim://still?pace=fast", True)):
        driver = driver_for(url)
        assert driver.can_flash is expected and UtcDriver(driver).can_flash is expected, url
        with driver:
            assert driver.can_flash is expected and can_flash(Connected(driver)) is expected, url
            if url.startswith("serial"):   # firmware that says it keeps no calibration record
                driver.info.calibration_store = False
                assert not driver.can_flash and not UtcDriver(driver).can_flash
                assert not can_flash(Connected(driver))


def test_flash_on_a_device_that_cannot_hold_offsets_is_refused_at_check_and_start(tmp_path):
    # every connect would fail to flash and be retried for ever, recording nothing
    path = tmp_path / "d.yaml"
    path.write_text(yaml.safe_dump({"output": "out", "devices": [
        {"url": "i2c-sim://mpu9250?rig=still", "name": "chip", "flash": True},
        {"url": "sim://still", "name": "plain", "flash": True}]}))
    with pytest.raises(ConfigError, match=r"^devices\[1\]\.flash: a sim:// device cannot hold offsets "
                                          r"\(device 'plain'\)"):
        check_config(load_config(path))
    from accelrig.daemon.service import Daemon

    with pytest.raises(ConfigError, match=r"^devices\[1\]\.flash"):
        Daemon(path)


def test_a_damaged_store_file_warns_at_check_and_the_daemon_takes_the_older_profile(tmp_path):
    """ExecStartPre runs `daemon check`: a half-copied profile must not stop every device after a reboot, and the
    device it belongs to records with its older profile, told which file to repair, never to recalibrate."""
    from accelrig.acquisition.driver import driver_for
    from accelrig.daemon.device import DeviceRunner
    from accelrig.profiles import load_profile
    from accelrig.profiles.store import ProfileStore

    driver = driver_for("sim://still?seed=3")
    info = driver.open()
    driver.close()
    profile = load_profile(REPO / "profiles" / "example-static_faces-vp.yaml")
    profile.data["device"].update(identity=info.identity, range_g=info.range_g, scale=info.scale)
    store = ProfileStore(tmp_path / "store")
    good = store.add(profile)
    damaged = good.parent / "20991125T040000Z-static.yaml"   # newer than the good one
    damaged.write_text("calibration: {procedure: static\n")
    config = parse_config({"output": str(tmp_path / "out"), "profile_store": str(store.root),
                           "devices": [{"url": "sim://still?seed=3", "name": "pier", "output": "calibrated"}]})
    notes = check_config(config)   # was: ProfileError, exit 6
    assert any(n.startswith("WARNING: profile store: skipped") and str(damaged) in n for n in notes), notes
    log = []
    runner = DeviceRunner(config.devices[0], config, log.append)
    runner._problems, runner._problem_sources = [], set()
    assert runner._choose_profile(info).path == good and runner.profile_problem is None
    assert any(str(damaged) in line and "repair or remove it" in line for line in log), log
    good.unlink()   # only the damaged file left: recording raw, told to repair it
    assert runner._choose_profile(info) is None
    assert str(damaged) in runner.profile_problem and "repair or remove that file" in runner.profile_problem
    assert "calibrate the device" not in runner.profile_problem


def test_the_serial_driver_is_given_the_daemons_stall_limit_unless_its_url_sets_its_own(tmp_path):
    """One stall limit per device: the serial driver cut a silent device after its own 2 s as "disconnected",
    so the daemon's stall_seconds and its documented "stalled: ..." cause never happened."""
    from accelrig.daemon.device import DeviceRunner
    from accelrig.errors import DeviceStalled

    config = parse_config({"output": str(tmp_path), "stall_seconds": 0.4, "devices": [
        {"name": "ser", "url": "serial-sim://still?seed=4&rate=200&stall_at=0.2&stall_for=inf"},
        {"name": "own", "url": "serial-sim://still?seed=4&rate=200&stall=0.3"},
        {"name": "plain", "url": "sim://still"}]})
    limits = [DeviceRunner(d, config, lambda line: None).stall_limit for d in config.devices]
    assert limits == [0.4, 0.3, 0.4]
    driver = DeviceRunner(config.devices[0], config, lambda line: None)._driver()
    with driver:
        assert driver.stall_timeout == 0.4     # was 2, whatever the daemon's stall_seconds
        with pytest.raises(DeviceStalled, match=r"sent no data for 0.4 s: the device stalled") as err:
            for _ in range(200):
                driver.read(0.05)
    assert err.value.seconds == 0.4
    assert str(driver.url.raw) == config.devices[0].url    # the URL as configured, in every message


def wait_until_true(condition, timeout: float = 60.0) -> None:
    import time

    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def test_a_reload_whose_old_runner_hangs_hands_the_directory_over_when_it_returns(tmp_path, monkeypatch, capsys):
    """A restarted device whose old runner took longer than STOP_SECONDS to stop: the old one kept the
    directory's lock, and the new one was refused beside it and retried with its backoff, its gap blamed on a
    crash.  Now the new one waits, says so, and starts once the old one has returned and closed its segments."""
    from accelrig.daemon import service
    from accelrig.daemon.device import WAITING_FOR_PREVIOUS
    from accelrig.recording import read_segments
    from accelrig_drivers.sim import SimDriver

    monkeypatch.setattr(service, "STOP_SECONDS", 0.2)
    release, hang = threading.Event(), threading.Event()
    close = SimDriver.close

    def close_that_hangs(self):   # a driver call that outlasts the reload's wait
        if hang.is_set():
            assert release.wait(60)
        close(self)

    monkeypatch.setattr(SimDriver, "close", close_that_hangs)
    path = tmp_path / "d.yaml"

    def configure(rate):
        path.write_text(yaml.safe_dump({**MINIMAL, "output": str(tmp_path / "out"),
                                        "devices": [{"url": f"sim://still?seed=1&rate={rate}", "name": "a"}]}))

    configure(200)
    daemon = service.Daemon(path)
    old = daemon._add(daemon.config.devices[0])
    old.start()
    try:
        wait_until_true(lambda: old.counts.written > 0)
        hang.set()
        configure(100)
        daemon.reload()
        new = daemon.runners["a"]
        assert new is not old and not old.join(0)
        assert "its new run starts then" in capsys.readouterr().err
        wait_until_true(lambda: new.status()["state"] == "waiting")
        assert new.status()["error"] == WAITING_FOR_PREVIOUS
        hang.clear()
        release.set()
        wait_until_true(lambda: new.counts.written > 0)
        assert old.join(5) and new.counts.failed_connects == 0 and new.counts.connects == 1
    finally:
        hang.clear()
        release.set()
        daemon._shutdown()
    events = [json.loads(line) for line in (tmp_path / "out" / "a" / "journal.jsonl").read_text().splitlines()]
    kinds = [e["event"] for e in events]
    assert "connect_failed" not in kinds
    # the old run stopped (its last sample in the journal) before the new one connected
    first_stop = kinds.index("stop")
    assert events[first_stop]["reason"] == "restarted: its configuration changed"
    assert kinds.index("connect", first_stop) > first_stop
    causes = [g["cause"] for g in read_segments(tmp_path / "out" / "a").meta["gaps"]]
    assert causes == ["not recording: restarted: its configuration changed"], causes
