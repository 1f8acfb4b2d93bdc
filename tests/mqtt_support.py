"""A real Mosquitto for the fleet tests (test_fleet.py, test_tui_fleet.py): free loopback ports, a password
file, an ACL, persistence, and a TLS listener with a CA made at test time when openssl is there."""

import getpass
import random
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

DAEMON_USER, DAEMON_PASSWORD = "gw-north", "north-secret"
COLLECTOR_USER, COLLECTOR_PASSWORD = "collector", "collector-secret"
ACL = f"""user {COLLECTOR_USER}
topic read accelrig/#

user {DAEMON_USER}
topic write accelrig/north/a/#
topic write accelrig/north/b/#
"""


def ephemeral_ports() -> range:
    """The ports the kernel hands out for outgoing connections (and for bind to port 0)."""
    try:
        low, high = map(int, Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split())
    except (OSError, ValueError):
        low, high = 32768, 60999
    return range(low, high + 1)


def free_port() -> int:
    """A loopback port nothing listens on now, below the ephemeral range when there is room there (no outgoing
    connection is given it as its own port meanwhile).  Between this and a server binding it another process
    can still take it: Broker.start picks new ports when mosquitto finds its port taken."""
    ephemeral = ephemeral_ports()
    candidates = range(20000, ephemeral.start) if ephemeral.start > 21000 else ephemeral
    for _ in range(100):
        port = random.choice(candidates)
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def make_ca(directory: Path) -> dict | None:
    """A CA and a broker certificate for 127.0.0.1, made now with openssl (None without openssl)."""
    if shutil.which("openssl") is None:
        return None
    d = directory

    def ssl(*args):
        subprocess.run(["openssl", *args], cwd=d, check=True, capture_output=True, timeout=30)

    ssl("req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout", "ca.key",
        "-out", "ca.crt", "-days", "2", "-subj", "/CN=accelrig test CA")
    ssl("req", "-new", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes", "-keyout",
        "server.key", "-out", "server.csr", "-subj", "/CN=127.0.0.1")
    (d / "san.ext").write_text("subjectAltName=IP:127.0.0.1\n")
    ssl("x509", "-req", "-in", "server.csr", "-CA", "ca.crt", "-CAkey", "ca.key", "-CAcreateserial", "-out",
        "server.crt", "-days", "2", "-extfile", "san.ext")
    return {"ca": d / "ca.crt", "cert": d / "server.crt", "key": d / "server.key"}


class Broker:
    """A real Mosquitto on loopback ports of its own, with a password file, an ACL and persistence (and a
    TLS listener when openssl is there).  stop() and start() again keep its ports: clients reconnect to the
    same URL."""

    def __init__(self, directory: Path):
        self.directory = directory
        self.tls = make_ca(directory)
        self.port = free_port()
        self.tls_port = free_port() if self.tls else None
        passwd = directory / "passwd"
        passwd.touch()
        for user, password in ((DAEMON_USER, DAEMON_PASSWORD), (COLLECTOR_USER, COLLECTOR_PASSWORD)):
            subprocess.run(["mosquitto_passwd", "-b", str(passwd), user, password], check=True, timeout=30)
        (directory / "acl").write_text(ACL)
        self.conf = directory / "mosquitto.conf"
        self.proc = None
        self.started = False   # once it has run, its ports are the ones the clients know

    def write_conf(self) -> None:
        # as root, mosquitto would switch to the user "mosquitto", who cannot read pytest's private tmp
        d = self.directory
        lines = [f"user {getpass.getuser()}", "per_listener_settings false", "allow_anonymous false",
                 f"password_file {d / 'passwd'}", f"acl_file {d / 'acl'}", "persistence true",
                 f"persistence_location {d}/", "max_queued_messages 100000", "log_dest stderr",
                 f"listener {self.port} 127.0.0.1"]
        if self.tls:
            lines += [f"listener {self.tls_port} 127.0.0.1", f"cafile {self.tls['ca']}",
                      f"certfile {self.tls['cert']}", f"keyfile {self.tls['key']}"]
        self.conf.write_text("\n".join(lines) + "\n")

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self) -> None:
        """Start mosquitto and wait until it runs with every listener open.  A port taken since free_port()
        chose it (another test, another worker): new ports the first time; on a restart, the same ports
        again until they are free (the clients know them)."""
        deadline = time.monotonic() + 20
        while True:
            self.write_conf()
            if self._run_once(deadline):
                self.started = True
                return
            assert time.monotonic() < deadline, f"mosquitto found its ports taken until the deadline: {self.log()}"
            if self.started:
                time.sleep(0.2)
            else:
                self.port = free_port()
                self.tls_port = free_port() if self.tls else None

    def log(self) -> str:
        path = self.directory / "mosquitto.log"
        return path.read_text(errors="replace") if path.exists() else ""

    def _run_once(self, deadline: float) -> bool:
        """True once this mosquitto says it runs (every listener bound); False when it exits because a port
        is in use (it binds them all before it says so)."""
        log_path = self.directory / "mosquitto.log"
        offset = log_path.stat().st_size if log_path.exists() else 0
        with open(log_path, "ab") as log:
            self.proc = subprocess.Popen(["mosquitto", "-c", str(self.conf)], stdout=log, stderr=log)
        while time.monotonic() < deadline:
            with open(log_path, "rb") as fh:
                fh.seek(offset)
                text = fh.read().decode(errors="replace")
            if " running" in text:
                return True
            if self.proc.poll() is not None:
                assert "Address already in use" in text, text
                return False
            time.sleep(0.05)
        raise AssertionError(f"mosquitto did not start within 20 s:\n{self.log()}")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)   # saves its persistence file (the sessions) on the way out
            self.proc.wait(10)


@pytest.fixture
def broker(tmp_path):
    (tmp_path / "broker").mkdir()
    b = Broker(tmp_path / "broker")
    b.start()
    yield b
    b.stop()
