"""Fleets against a real Mosquitto: daemon -> broker -> collector, a broker away mid-run, TLS, passwords, ACL.

The broker runs as ``mosquitto -c <tmpconf>`` on free loopback ports (never the system service),
with a password file, an ACL, persistence (so the collector's persistent session survives the
broker's restart) and, when openssl is there, a TLS listener with a CA made here.

The checks: every sample of the daemon's local files is in the collector's files, or an explicit
gap record there stands where it is missing, with the exact count.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from accelrig.segments import read_arrays
from mqtt_support import COLLECTOR_PASSWORD, COLLECTOR_USER, DAEMON_PASSWORD, DAEMON_USER, free_port

# the broker fixture comes from mqtt_support through conftest.py
pytestmark = pytest.mark.skipif(
    shutil.which("mosquitto") is None and not os.environ.get("CI"),
    reason="mosquitto is not installed (apt-get install mosquitto); CI installs it and runs these tests")


def accelrig(*args, env=None, log: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "accelrig", *args], stdout=open(log, "ab"),
                            stderr=subprocess.STDOUT, env={**os.environ, **(env or {})})


def samples(directory: Path):
    """(times in ns, counts, gap records) of one device's segments."""
    t, acc, _, _, meta = read_arrays(directory, units="counts")
    t_ns = meta["time_origin_ns"] + np.rint(t * 1e9).astype(np.int64)
    return t_ns, acc.astype(np.int16), meta["gaps"]


def wait_for(condition, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"timed out waiting for {what}")


def collected_to_the_end(local: Path, collected: Path) -> bool:
    """The collector's files reach the last sample of the (stopped) daemon's local files.  Messages arrive in
    order, so everything before it has arrived too: the condition to stop the collector on (a fixed second
    raced the broker's backlog on a loaded machine)."""
    from accelrig.errors import AccelrigError

    try:
        local_t, got_t = samples(local)[0], samples(collected)[0]
    except (AccelrigError, OSError, ValueError):   # no segment yet, or its first frame not written yet
        return False
    return bool(local_t.size and got_t.size and got_t[-1] >= local_t[-1])


def daemon_status(config: Path) -> dict:
    """What ``accelrig daemon status --json`` prints, through the same socket client in this process
    (a new process per poll cost about a second of start-up on a loaded machine; test_daemon.py runs the command)."""
    from accelrig.daemon.config import load_config
    from accelrig.daemon.status import StatusError, query

    try:
        answer = query(load_config(config).status_socket)
    except StatusError:
        return {}
    return {d["name"]: d for d in answer["devices"]}


def metric(port: int, name: str, device: str) -> float | None:
    """One sample of the daemon's Prometheus metrics, or None when it is not there."""
    import urllib.request

    text = urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10).read().decode()
    for line in text.splitlines():
        if line.startswith(f'{name}{{device="{device}"}} ') or line.startswith(f'{name}_total{{device="{device}"}} '):
            return float(line.rsplit(" ", 1)[1])
    return None


OUTAGE_S = 30.0   # the network cut; the one test that waits it (marked slow, run in CI)


@pytest.mark.slow
def test_daemon_to_collector_through_a_broker_that_goes_away(broker, tmp_path):
    (tmp_path / "daemon.pass").write_text(DAEMON_PASSWORD + "\n")
    # reconnect_max 2: the daemons find the broker back within 2 s (the default, 10 s, is the collector's)
    common = {"site": "north", "username": DAEMON_USER, "password_file": str(tmp_path / "daemon.pass"),
              "status_seconds": 1, "reconnect_max": 2}
    mqtt_a = {**common, "broker": broker.url}
    if broker.tls:   # device a's daemon goes through the TLS listener
        mqtt_a.update(broker=f"mqtts://127.0.0.1:{broker.tls_port}", ca_file=str(broker.tls["ca"]))
    # two daemons: a with room to spool the whole outage, b with a spool too small for it
    metrics_port = free_port()
    configs = {
        "a": {"output": str(tmp_path / "out-a"), "status_interval": 0, "metrics_port": metrics_port,
              "devices": [{"url": "sim://still?seed=1&pace=realtime&rate=500", "name": "a"}], "mqtt": mqtt_a},
        "b": {"output": str(tmp_path / "out-b"), "status_interval": 0,
              "devices": [{"url": "sim://still?seed=2&pace=realtime&rate=500", "name": "b"}],
              "mqtt": {**common, "broker": broker.url, "spool_megabytes": 0.01}},
    }
    collector = accelrig("collect", "--broker", broker.url, "--output", str(tmp_path / "fleet"),
                         "--username", COLLECTOR_USER, "--password-env", "COLLECT_PW",
                         env={"COLLECT_PW": COLLECTOR_PASSWORD}, log=tmp_path / "collect.log")
    wait_for(lambda: "connected to" in (tmp_path / "collect.log").read_text() or collector.poll() is not None,
             60, "the collector to connect")
    assert collector.poll() is None, (tmp_path / "collect.log").read_text()
    daemons = {}
    for name, config in configs.items():
        path = tmp_path / f"{name}.yaml"
        path.write_text(yaml.safe_dump(config))
        daemons[name] = (accelrig("daemon", "--config", str(path), log=tmp_path / f"{name}.log"), path)
    try:
        wait_for(lambda: all((tmp_path / "fleet" / "north" / n).is_dir() for n in "ab"), 60,
                 "both devices at the collector")
        time.sleep(1.5)
        sent_before = metric(metrics_port, "accelrig_mqtt_messages_sent", "a")
        assert sent_before > 0 and metric(metrics_port, "accelrig_mqtt_connected", "a") == 1
        broker.stop()                      # the network cut: nothing reaches the broker for OUTAGE_S
        time.sleep(OUTAGE_S)
        for name, (_proc, path) in daemons.items():
            st = daemon_status(path)[name]
            assert st["mqtt"]["connected"] is False
            assert st["mqtt"]["spooled"] > 0, st
        # the outage in the daemon's Prometheus metrics: not connected, the blocks on disk
        assert metric(metrics_port, "accelrig_mqtt_connected", "a") == 0
        assert metric(metrics_port, "accelrig_mqtt_spooled_messages", "a") >= 0.8 * OUTAGE_S / 0.2 * 0.5
        broker.start()
        # the backlog goes out in order; b's spool overflowed and says so
        wait_for(lambda: all((s := daemon_status(p).get(n)) and s["mqtt"]["connected"] and s["mqtt"]["spooled"] <= 3
                             for n, (_, p) in daemons.items()), 60, "the spools to drain")
        status_b = daemon_status(daemons["b"][1])["b"]["mqtt"]
        assert status_b["dropped_samples"] > 0 and status_b["spool_gaps"] >= 1
        status_a = daemon_status(daemons["a"][1])["a"]["mqtt"]
        assert status_a["reconnects"] >= 1 and status_a["dropped_samples"] == 0
        assert metric(metrics_port, "accelrig_mqtt_reconnects", "a") == status_a["reconnects"]
        assert metric(metrics_port, "accelrig_mqtt_messages_sent", "a") > sent_before
        assert metric(metrics_port, "accelrig_mqtt_messages_acknowledged", "a") > 0
        assert metric(metrics_port, "accelrig_mqtt_dropped_samples", "a") == 0
        time.sleep(1.0)
        # the fleet table from the retained messages, while they run
        fleet = subprocess.run([sys.executable, "-m", "accelrig", "fleet", "--broker", broker.url, "--username",
                                COLLECTOR_USER, "--password-env", "COLLECT_PW", "--json"], capture_output=True,
                               text=True, timeout=30, env={**os.environ, "COLLECT_PW": COLLECTOR_PASSWORD})
        assert fleet.returncode == 0, fleet.stderr
        rows = {r["device"]: r for r in json.loads(fleet.stdout)}
        assert set(rows) == {"a", "b"} and rows["a"]["state"] == "streaming" and rows["a"]["rate"] > 400
        for proc, _ in daemons.values():
            proc.send_signal(signal.SIGTERM)
            assert proc.wait(15) == 0
    finally:
        for proc, _ in daemons.values():
            if proc.poll() is None:
                proc.kill()
    for name in "ab":
        log = (tmp_path / f"{name}.log").read_text()
        assert "left in the spool" not in log, log
        assert DAEMON_PASSWORD not in log and DAEMON_PASSWORD not in (tmp_path / f"out-{name}" / name /
                                                                       "journal.jsonl").read_text()
    # the collector finds the broker back within its reconnect_max (10 s) and takes what the broker kept for it
    wait_for(lambda: "reconnected to" in (tmp_path / "collect.log").read_text(), 60, "the collector to reconnect")
    wait_for(lambda: all(collected_to_the_end(tmp_path / f"out-{n}" / n, tmp_path / "fleet" / "north" / n)
                         for n in "ab"), 60, "the collector to take the daemons' last samples")
    collector.send_signal(signal.SIGTERM)
    assert collector.wait(15) == 0
    collect_log = (tmp_path / "collect.log").read_text()
    assert COLLECTOR_PASSWORD not in collect_log

    # a: every local sample at the collector, the same counts, nothing "not received"
    local_t, local_c, local_gaps = samples(tmp_path / "out-a" / "a")
    got_t, got_c, got_gaps = samples(tmp_path / "fleet" / "north" / "a")
    assert local_t.size > 2500
    at = np.searchsorted(got_t, local_t)
    assert np.all(at < got_t.size) and np.array_equal(got_t[at], local_t), "samples missing at the collector"
    assert np.array_equal(got_c[at], local_c)
    assert not [g for g in got_gaps if "not received" in g["cause"] or "spool" in g["cause"]], got_gaps
    assert [g["cause"] for g in got_gaps] == [g["cause"] for g in local_gaps]

    # b: each local sample the collector lacks stands where a spool-overflow gap record says so, exactly
    local_t, local_c, _ = samples(tmp_path / "out-b" / "b")
    got_t, got_c, got_gaps = samples(tmp_path / "fleet" / "north" / "b")
    missing = np.setdiff1d(local_t, got_t)
    spool_gaps = [g for g in got_gaps if "spool full" in g["cause"]]
    assert missing.size > 0 and spool_gaps
    assert sum(g["missing"] for g in spool_gaps) == missing.size
    assert set(np.searchsorted(got_t, missing).tolist()) <= {g["index"] for g in spool_gaps}
    kept = np.isin(local_t, got_t)
    assert np.array_equal(got_c[np.searchsorted(got_t, local_t[kept])], local_c[kept])
    assert not [g for g in got_gaps if "not received" in g["cause"]], got_gaps


def test_wrong_password_is_refused_in_one_line(broker, tmp_path):
    result = subprocess.run([sys.executable, "-m", "accelrig", "collect", "--broker", broker.url, "--output",
                             str(tmp_path / "fleet"), "--username", COLLECTOR_USER, "--password-env", "PW"],
                            capture_output=True, text=True, timeout=30, env={**os.environ, "PW": "wrong"})
    assert result.returncode != 0
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "refused" in lines[0] and "password" in lines[0].lower(), result.stderr
    assert "wrong" not in result.stderr


def test_acl_keeps_a_daemon_to_its_own_topics(broker):
    import threading

    import paho.mqtt.client as mqtt

    subscribed = threading.Event()

    def client(user, password, received=None):
        c = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=f"t-{user}-{time.time_ns()}")
        c.username_pw_set(user, password)
        if received is not None:
            c.on_message = lambda cl, ud, m: received.append(m.topic)
            c.on_subscribe = lambda *_: subscribed.set()
        c.connect("127.0.0.1", broker.port)
        c.loop_start()
        return c

    received: list[str] = []
    reader = client(COLLECTOR_USER, COLLECTOR_PASSWORD, received)
    reader.subscribe("accelrig/#", 1)
    # the broker acknowledged the subscription: what is published from now on reaches the reader (a fixed
    # half second could end first on a loaded machine, and the allowed message went to nobody)
    assert subscribed.wait(60), "the broker never acknowledged the subscription"
    daemon = client(DAEMON_USER, DAEMON_PASSWORD)
    daemon.publish("accelrig/south/c/data", b"not mine", qos=1).wait_for_publish(5)
    daemon.publish("accelrig/north/a/data", b"mine", qos=1).wait_for_publish(5)
    wait_for(lambda: "accelrig/north/a/data" in received, 30, "the allowed message")
    time.sleep(0.3)
    assert "accelrig/south/c/data" not in received
    for c in (reader, daemon):
        c.disconnect()
        c.loop_stop()


def test_payload_round_trip_and_refusals():
    from accelrig.daemon import wire
    from accelrig.errors import DataError

    t = 1_795_000_000_000_000_000 + np.arange(5, dtype=np.int64) * 488_281
    counts = np.arange(15, dtype=np.int16).reshape(5, 3) - 7
    m = wire.decode(wire.encode_data(7, 3, 100, t, counts, 0.000598, "id@2026"))
    assert (m.kind, m.epoch, m.seq, m.first_sample, m.profile, m.scale) == (wire.DATA, 7, 3, 100, "id@2026", 0.000598)
    assert np.array_equal(m.t_ns, t) and np.array_equal(m.counts, counts)
    g = wire.decode(wire.encode_gap(7, 4, 105, int(t[-1]), 0.000598, "", 12, "FIFO overflow", 0.01))
    assert g.gap == {"samples": 12, "cause": "FIFO overflow", "seconds": 0.01}
    assert wire.split_block(np.array([0, 2**31, 2**32, 2**32 + 1], dtype=np.int64)) == [(0, 2), (2, 4)]
    with pytest.raises(DataError, match="version"):
        wire.decode(b"ACCB\x02" + bytes(60))
    with pytest.raises(DataError, match="credentials"):
        wire.parse_broker("mqtt://user:pw@host")


@pytest.mark.parametrize("mqtt, message", [
    ({"broker": "http://x", "site": "n"}, "mqtt.broker"),
    ({"broker": "mqtt://x", "site": "n", "password_file": "p"}, "a password needs a user name"),
    ({"broker": "mqtt://x", "site": "n", "username": "u", "password_file": "p", "password_env": "E"}, "not both"),
    ({"broker": "mqtt://x", "site": "n", "ca_file": "ca.crt"}, "CA file is for TLS"),
    ({"broker": "mqtt://u:pw@x", "site": "n"}, "credentials do not belong"),
    ({"broker": "mqtt://x", "site": "a/b"}, "mqtt.site"),
    ({"broker": "mqtt://x", "site": "n", "reconnect_max": 0}, "mqtt.reconnect_max"),
])
def test_mqtt_config_refused_naming_the_field(mqtt, message):
    from accelrig.daemon.config import ConfigError, parse_config

    with pytest.raises(ConfigError, match=message) as info:
        parse_config({"output": "/tmp/x", "devices": [{"url": "sim://still", "name": "a"}], "mqtt": mqtt})
    assert "pw" not in str(info.value)


def fleet_state(broker) -> str | None:
    out = subprocess.run([sys.executable, "-m", "accelrig", "fleet", "--broker", broker.url, "--username",
                          COLLECTOR_USER, "--password-env", "PW", "--json", "--timeout", "5"], capture_output=True,
                         text=True, timeout=30, env={**os.environ, "PW": COLLECTOR_PASSWORD})
    assert out.returncode == 0, out.stderr
    rows = json.loads(out.stdout)
    return rows[0]["state"] if rows else None


def test_a_daemon_killed_while_the_broker_is_away_sends_its_spool_at_the_next_start(broker, tmp_path):
    """kill -9 with a spool on disk, the broker back, the daemon started again: the old run's blocks
    go out first, then the new run's (with its "not recording" gap); the collector, restarted too,
    keeps its place (collector.json) and holds every sample of the local files.  The retained
    status says offline (last will) after a kill, stopped after SIGTERM."""
    (tmp_path / "daemon.pass").write_text(DAEMON_PASSWORD + "\n")
    config = tmp_path / "a.yaml"
    config.write_text(yaml.safe_dump({
        "output": str(tmp_path / "out"), "status_interval": 0,
        "devices": [{"url": "sim://still?seed=3&pace=realtime&rate=500", "name": "a"}],
        "mqtt": {"broker": broker.url, "site": "north", "username": DAEMON_USER,
                 "password_file": str(tmp_path / "daemon.pass"), "status_seconds": 1}}))
    env = {"COLLECT_PW": COLLECTOR_PASSWORD}
    collect_args = ("collect", "--broker", broker.url, "--output", str(tmp_path / "fleet"), "--username",
                    COLLECTOR_USER, "--password-env", "COLLECT_PW")
    collector = accelrig(*collect_args, env=env, log=tmp_path / "collect.log")
    daemon = accelrig("daemon", "--config", str(config), log=tmp_path / "a.log")
    try:
        wait_for(lambda: (tmp_path / "fleet" / "north" / "a").is_dir(), 60, "the device at the collector")
        time.sleep(1.0)
        collector.send_signal(signal.SIGTERM)        # the collector restarts while all this happens
        assert collector.wait(15) == 0
        broker.stop()
        spool = tmp_path / "out" / "a" / "spool"
        wait_for(lambda: len(list(spool.glob("*.msg"))) >= 3, 60, "blocks in the spool while the broker is away")
        daemon.kill()                                # kill -9 with the outage's blocks in the spool
        daemon.wait(10)
        spooled = list(spool.glob("*.msg"))
        assert spooled, "nothing was spooled while the broker was away"
        broker.start()
        collector = accelrig(*collect_args, env=env, log=tmp_path / "collect.log")
        daemon = accelrig("daemon", "--config", str(config), log=tmp_path / "a.log")
        wait_for(lambda: "spooled message(s) to send" in (tmp_path / "a.log").read_text(), 60,
                 "the restarted daemon to find its spool")
        wait_for(lambda: not set(spooled) & set(spool.glob("*.msg")), 60, "the old run's spool to go out")
        daemon.kill()                                # the broker sees it vanish: the last will says offline
        daemon.wait(10)
        wait_for(lambda: fleet_state(broker) == "offline", 60, "the last will (offline)")
        daemon = accelrig("daemon", "--config", str(config), log=tmp_path / "a.log")
        wait_for(lambda: fleet_state(broker) == "streaming", 60, "the daemon streaming again")
        daemon.send_signal(signal.SIGTERM)
        assert daemon.wait(15) == 0
        assert fleet_state(broker) == "stopped"
        wait_for(lambda: collected_to_the_end(tmp_path / "out" / "a", tmp_path / "fleet" / "north" / "a"), 60,
                 "the collector to take the daemon's last samples")
        collector.send_signal(signal.SIGTERM)
        assert collector.wait(15) == 0
    finally:
        for proc in (daemon, collector):
            if proc.poll() is None:
                proc.kill()
    assert not list((tmp_path / "out" / "a" / "spool").glob("*.msg"))
    local_t, local_c, local_gaps = samples(tmp_path / "out" / "a")
    got_t, got_c, got_gaps = samples(tmp_path / "fleet" / "north" / "a")
    at = np.searchsorted(got_t, local_t)
    assert np.all(at < got_t.size) and np.array_equal(got_t[at], local_t), "samples missing at the collector"
    assert np.array_equal(got_c[at], local_c)
    assert not [g for g in got_gaps if "not received" in g["cause"]], got_gaps
    assert any("not recording" in g["cause"] for g in got_gaps)
    assert json.loads((tmp_path / "fleet" / "north" / "a" / "collector.json").read_text())["next_seq"] > 0


def test_a_full_spool_drops_the_oldest_blocks_as_one_exact_gap(tmp_path):
    """No broker: the spool's bound folds the oldest blocks, and the earlier fold, into one gap message."""
    from accelrig.daemon import wire
    from accelrig.daemon.config import MqttConfig
    from accelrig.daemon.mqtt import Publisher

    settings = MqttConfig(broker="mqtt://127.0.0.1:1", site="north", spool_megabytes=0.003)
    logs: list[str] = []
    publisher = Publisher(settings, "a", tmp_path / "spool", dict, logs.append)
    publisher.announce({}, 0.0006, "")
    counts = np.zeros((100, 3), np.int16)
    for k in range(10):    # 10 blocks of 100 samples, 1052 bytes each, against a 3000-byte bound
        publisher.block(1.795e9 + k * 0.1 + np.arange(100) * 1e-3, counts)
    messages = [wire.decode(p.read_bytes()) for p in sorted((tmp_path / "spool").glob("*.msg"))]
    gap, rest = messages[0], messages[1:]
    assert gap.kind == wire.GAP and gap.gap["spool"] and gap.gap["first_seq"] == 0 and gap.gap["from_sample"] == 0
    assert gap.gap["samples"] == publisher.counts["dropped_samples"] == gap.first_sample
    assert all(m.kind == wire.DATA for m in rest) and rest[0].first_sample == gap.first_sample
    assert [m.seq for m in rest] == list(range(gap.seq + 1, 10))
    assert gap.gap["samples"] + sum(m.samples for m in rest) == 1000
    assert len(logs) == 1 and "spool over" in logs[0]


def test_meta_and_profile_are_retained(broker, tmp_path):
    import paho.mqtt.client as mqtt

    from accelrig.daemon.config import MqttConfig
    from accelrig.daemon.mqtt import Publisher

    (tmp_path / "pw").write_text(DAEMON_PASSWORD)
    settings = MqttConfig(broker=broker.url, site="north", username=DAEMON_USER, password_file=str(tmp_path / "pw"))
    publisher = Publisher(settings, "a", tmp_path / "spool", dict, lambda line: None)
    publisher.announce({"identity": "sim-1"}, 0.0006, "sim-1@2026", {"format": "accelrig-profile"})
    publisher.start()
    wait_for(lambda: publisher.connected, 60, "the publisher to connect")
    publisher.close()
    got: dict[str, bytes] = {}
    reader = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="t-retained")
    reader.username_pw_set(COLLECTOR_USER, COLLECTOR_PASSWORD)
    reader.on_message = lambda c, u, m: got.__setitem__(m.topic.rsplit("/", 1)[1], m.payload)
    reader.connect("127.0.0.1", broker.port)
    reader.subscribe("accelrig/north/a/+", 1)
    reader.loop_start()
    try:
        wait_for(lambda: {"meta", "profile", "status"} <= set(got), 60, "the retained messages")
    finally:
        reader.disconnect()
        reader.loop_stop()
    assert json.loads(got["profile"]) == {"format": "accelrig-profile"}
    assert json.loads(got["meta"])["identity"] == "sim-1"
    assert json.loads(got["status"])["state"] == "stopped"


def test_a_device_recording_raw_for_want_of_its_profile_says_so_to_the_fleet(broker, tmp_path):
    from accelrig.daemon.fleet import format_table, gather, rows

    (tmp_path / "daemon.pass").write_text(DAEMON_PASSWORD + "\n")
    config = {"output": str(tmp_path / "out"), "profile_store": str(tmp_path / "store"), "status_interval": 0,
              "devices": [{"url": "sim://still?seed=11&rate=200", "name": "a", "output": "calibrated"}],
              "mqtt": {"broker": broker.url, "site": "north", "username": DAEMON_USER,
                       "password_file": str(tmp_path / "daemon.pass"), "status_seconds": 0.5}}
    path = tmp_path / "d.yaml"
    path.write_text(yaml.safe_dump(config))
    proc = accelrig("daemon", "--config", str(path), log=tmp_path / "d.log")
    try:
        def seen():
            table = rows(gather(broker.url, username=COLLECTOR_USER, password=COLLECTOR_PASSWORD, timeout=2))
            return table if table and table[0]["state"] == "recording raw" else None

        (row,) = wait_for(seen, 60, "the fleet to see the device recording raw")
        assert row["profile"] is None and row["error"].startswith("recording raw: no profile for 'sim-random-11'")
        assert "north/a: recording raw: no profile for 'sim-random-11'" in format_table([row])
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=15)


def test_fleet_table_fits_80_columns_and_keeps_every_column():
    """`accelrig fleet` at 80 columns (with the recalibration column): no line wider, every cell printed."""
    from accelrig.daemon.fleet import cells, columns, format_table

    row = {"site": "north-building", "device": "roof-accelerometer-3", "host": "raspberrypi-north-07",
           "state": "recording raw", "last_seen": "2026-11-25T03:00:00Z", "seconds_since_seen": 75.0,
           "rate": 2048.0, "nominal_rate": 2048.0, "gaps": 12, "missing": 40, "spooled": 1234,
           "spool_dropped_samples": 0, "profile": "static/map", "profile_created": "2026-10-01T00:00:00Z",
           "profile_age_seconds": 55 * 86400.0, "recalibration": "due",
           "error": "recording raw: no profile for 'sim-random-11' in the store: file it, then reload the daemon"}
    table = format_table([row], recalibrate_days=30)
    assert max(len(line) for line in table.splitlines()) <= 80, table
    words = table.split()
    assert all(all(word in words for word in cell.split()) for cell in cells(row, 30)), table
    assert all(any(title in line for line in table.splitlines()) for title in columns(30)), table
