"""A real Mosquitto for the fleet tests (test_fleet.py, test_tui_fleet.py): free loopback ports, a password
file, an ACL, persistence, and a TLS listener with a CA made at test time when openssl is there."""

import getpass
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


def free_port() -> int:
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
    def __init__(self, directory: Path):
        self.directory = directory
        self.port = free_port()
        self.tls = make_ca(directory)
        self.tls_port = free_port() if self.tls else None
        passwd = directory / "passwd"
        passwd.touch()
        for user, password in ((DAEMON_USER, DAEMON_PASSWORD), (COLLECTOR_USER, COLLECTOR_PASSWORD)):
            subprocess.run(["mosquitto_passwd", "-b", str(passwd), user, password], check=True, timeout=30)
        (directory / "acl").write_text(ACL)
        # as root, mosquitto would switch to the user "mosquitto", who cannot read pytest's private tmp
        lines = [f"user {getpass.getuser()}", "per_listener_settings false", "allow_anonymous false", f"password_file {passwd}",
                 f"acl_file {directory / 'acl'}", "persistence true", f"persistence_location {directory}/",
                 "max_queued_messages 100000", "log_dest stderr", f"listener {self.port} 127.0.0.1"]
        if self.tls:
            lines += [f"listener {self.tls_port} 127.0.0.1", f"cafile {self.tls['ca']}",
                      f"certfile {self.tls['cert']}", f"keyfile {self.tls['key']}"]
        self.conf = directory / "mosquitto.conf"
        self.conf.write_text("\n".join(lines) + "\n")
        self.proc = None

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self) -> None:
        log = open(self.directory / "mosquitto.log", "ab")
        self.proc = subprocess.Popen(["mosquitto", "-c", str(self.conf)], stdout=log, stderr=log)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            assert self.proc.poll() is None, (self.directory / "mosquitto.log").read_text()
            try:
                socket.create_connection(("127.0.0.1", self.port), 0.2).close()
                return
            except OSError:
                time.sleep(0.05)
        raise AssertionError("mosquitto did not listen within 10 s")

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
