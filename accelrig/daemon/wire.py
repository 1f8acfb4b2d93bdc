"""What travels over MQTT: the broker URL, the topics, the binary block payload, the client.

Shared by the publishing daemon (``daemon.mqtt``), ``accelrig collect`` (``daemon.collector``)
and ``accelrig fleet`` (``daemon.fleet``).  paho-mqtt is imported only by ``make_client``.

Topics, under a prefix (default ``accelrig``)::

    PREFIX/SITE/DEVICE/data     blocks of samples and gap records (binary, below), QoS 1
    PREFIX/SITE/DEVICE/status   JSON, retained; the last will replaces it with {"state": "offline", ...}
    PREFIX/SITE/DEVICE/meta     JSON, retained: device, profile, rate, payload version
    PREFIX/SITE/DEVICE/profile  JSON, retained: the whole profile in use (empty: none)

Payload of ``data`` (little-endian; ``HEADER`` below, 52 bytes, then the profile id, then the body)::

    4s   magic b"ACCB"
    u8   version (1)
    u8   kind: 1 data block, 2 gap record
    u16  length of the profile id (bytes of UTF-8 after the header)
    i64  epoch: the publisher's start, ns since 1970 (sequence numbers count within one epoch)
    u64  seq: 0, 1, 2 ... per device and epoch, data and gap messages alike
    u64  first_sample: index within the epoch of the block's first sample (of the next sample, for a gap)
    i64  t0_ns: UTC of the block's first sample (of the gap's start), ns since 1970
    u32  n: samples in the block (0 for a gap)
    f64  scale: m/s^2 per count
    data body: u32[n] sample times as ns after t0_ns, then i16[n][3] raw counts x, y, z
    gap body:  JSON {"samples": N or -1 (unknown), "cause": "...", "seconds": S or null}; a gap the
               publisher made of blocks it dropped from a full spool adds "spool": true and
               "first_seq", "from_sample": the first sequence number and sample it stands for
               (it carries the last dropped number, so those in between are not missing)

A receiver knows from ``seq`` which messages it has (a repeat is a duplicate) and from
``first_sample`` exactly how many samples a missing stretch held.
"""

from __future__ import annotations

import json
import os
import socket
import ssl
import struct
from dataclasses import dataclass
from urllib.parse import urlsplit

import numpy as np

from accelrig.errors import AccelrigError, DataError

MAGIC = b"ACCB"
VERSION = 1
DATA, GAP = 1, 2
HEADER = struct.Struct("<4sBBHqQQqId")
MAX_SPAN_NS = 2**32 - 1            # a block's times must fit u32 offsets from its first sample
DEFAULT_PREFIX = "accelrig"


class BrokerError(AccelrigError):
    """The MQTT broker cannot be reached or refuses us."""

    exit_code = 10


@dataclass(frozen=True)
class Broker:
    host: str
    port: int
    tls: bool

    def __str__(self) -> str:
        return f"{'mqtts' if self.tls else 'mqtt'}://{self.host}:{self.port}"


def parse_broker(url: str) -> Broker:
    """``mqtt://HOST[:PORT]`` (1883) or ``mqtts://HOST[:PORT]`` (TLS, 8883); no credentials in the URL."""
    parts = urlsplit(url)
    if parts.scheme not in ("mqtt", "mqtts") or not parts.hostname:
        raise DataError(f"broker {url!r}: expected mqtt://HOST[:PORT] or mqtts://HOST[:PORT] (TLS)")
    if parts.username or parts.password:
        raise DataError(f"broker {url.split('@')[-1]!r}: credentials do not belong in the URL",
                        "give username and password_file (or password_env) instead")
    try:
        port = parts.port
    except ValueError:
        raise DataError(f"broker {url!r}: the port is not a number") from None
    tls = parts.scheme == "mqtts"
    return Broker(parts.hostname, port or (8883 if tls else 1883), tls)


def read_password(password_file: str | None, password_env: str | None) -> str | None:
    """The password from a file (first line) or an environment variable; never echoed anywhere."""
    if password_file:
        try:
            with open(password_file, encoding="utf-8") as fh:
                return fh.readline().rstrip("\r\n")
        except OSError as exc:
            raise DataError(f"password_file {password_file}: cannot read ({exc.strerror})") from None
    if password_env:
        value = os.environ.get(password_env)
        if value is None:
            raise DataError(f"password_env: the environment variable {password_env} is not set")
        return value
    return None


def topic(prefix: str, site: str, device: str, kind: str) -> str:
    return f"{prefix}/{site}/{device}/{kind}"


def split_topic(prefix: str, name: str) -> tuple[str, str, str] | None:
    """(site, device, kind) of a topic under ``prefix``, or None."""
    head = prefix + "/"
    if not name.startswith(head):
        return None
    parts = name[len(head):].split("/")
    return tuple(parts) if len(parts) == 3 else None


# ---------------------------------------------------------------------- payload
@dataclass
class Message:
    kind: int
    epoch: int
    seq: int
    first_sample: int
    t0_ns: int
    scale: float
    profile: str
    t_ns: np.ndarray | None = None      # data: int64 (n,)
    counts: np.ndarray | None = None    # data: int16 (n, 3)
    gap: dict | None = None             # gap: samples, cause, seconds

    @property
    def samples(self) -> int:
        return 0 if self.counts is None else int(self.counts.shape[0])


def encode_data(epoch: int, seq: int, first_sample: int, t_ns: np.ndarray, counts: np.ndarray, scale: float,
                profile: str) -> bytes:
    n = int(t_ns.shape[0])
    offsets = t_ns - t_ns[0]
    if n and int(offsets[-1]) > MAX_SPAN_NS:
        raise ValueError("a block spans more than 4.29 s; split it (split_block)")
    pid = profile.encode()
    return b"".join((HEADER.pack(MAGIC, VERSION, DATA, len(pid), epoch, seq, first_sample, int(t_ns[0]), n, scale),
                     pid, offsets.astype("<u4").tobytes(), np.ascontiguousarray(counts, "<i2").tobytes()))


def encode_gap(epoch: int, seq: int, first_sample: int, t0_ns: int, scale: float, profile: str, samples: int,
               cause: str, seconds: float | None, extra: dict | None = None) -> bytes:
    pid = profile.encode()
    body = json.dumps({"samples": int(samples), "cause": cause, "seconds": seconds, **(extra or {})}).encode()
    return HEADER.pack(MAGIC, VERSION, GAP, len(pid), epoch, seq, first_sample, int(t0_ns), 0, scale) + pid + body


def decode(payload: bytes) -> Message:
    """A data-topic payload; DataError when it is not one this version reads."""
    if len(payload) < HEADER.size:
        raise DataError(f"payload of {len(payload)} bytes is shorter than the {HEADER.size}-byte header")
    magic, version, kind, plen, epoch, seq, first, t0, n, scale = HEADER.unpack_from(payload)
    if magic != MAGIC:
        raise DataError("payload does not start with b'ACCB' (not an accelrig block)")
    if version != VERSION:
        raise DataError(f"payload version {version}; this accelrig reads version {VERSION}",
                        "upgrade the collector to the daemons' version")
    at = HEADER.size
    profile = payload[at:at + plen].decode()
    at += plen
    message = Message(kind, epoch, seq, first, t0, scale, profile)
    if kind == DATA:
        if len(payload) != at + 10 * n:
            raise DataError(f"data payload of {len(payload)} bytes does not hold the {n} samples it announces")
        offsets = np.frombuffer(payload, "<u4", n, at)
        message.t_ns = t0 + offsets.astype(np.int64)
        message.counts = np.frombuffer(payload, "<i2", 3 * n, at + 4 * n).reshape(n, 3).astype(np.int16)
    elif kind == GAP:
        try:
            message.gap = json.loads(payload[at:])
        except ValueError:
            raise DataError("gap payload: the body is not JSON") from None
    else:
        raise DataError(f"payload kind {kind} is unknown")
    return message


def split_block(t_ns: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) pieces of a block, each spanning at most MAX_SPAN_NS."""
    pieces, start, n = [], 0, t_ns.shape[0]
    while start < n:
        stop = int(np.searchsorted(t_ns, t_ns[start] + MAX_SPAN_NS, "right"))
        pieces.append((start, stop))
        start = stop
    return pieces


# ---------------------------------------------------------------------- client
CONNECT_ERRORS = {
    1: "the broker refused the protocol version",
    2: "the broker refused the client id",
    3: "the broker is unavailable",
    4: "bad user name or password",
    5: "not authorised",
}


def make_client(client_id: str, broker: Broker, username: str | None, password: str | None,
                ca_file: str | None, clean: bool = False, reconnect_max: float = 10.0):
    """A paho client (MQTT 3.1.1) set up for ``broker``; not yet connected.

    ``clean=False``: a persistent session (the broker keeps our subscriptions and queues QoS 1
    messages for us while we are away).
    """
    try:
        import paho.mqtt.client as mqtt
    except ImportError:
        raise BrokerError("MQTT needs paho-mqtt, which is not installed",
                          "pip install 'accelrig[mqtt]'") from None
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=clean,
                         protocol=mqtt.MQTTv311)
    if username is not None:
        client.username_pw_set(username, password)
    if broker.tls:
        context = ssl.create_default_context(cafile=ca_file)
        client.tls_set_context(context)
    # paho doubles the wait after each failed try, from 1 s up to reconnect_max
    client.reconnect_delay_set(1, max(1, round(reconnect_max)))
    return client


def login_refused(reason) -> bool:
    """A refused CONNECT that a login would change (bad user name or password, not authorised):
    asking again with the same login is in vain."""
    return getattr(reason, "value", reason) in (4, 5, 134, 135)   # MQTT 3.1.1 codes, and paho's v5 style


def connect_error(broker: Broker, reason) -> str:
    """One line for a refused CONNECT (paho's reason code, v3 or v5 style)."""
    value = getattr(reason, "value", reason)
    text = CONNECT_ERRORS.get(value) or str(reason)
    if getattr(reason, "is_failure", False) and "not authorized" in str(reason).lower():
        text = "not authorised (bad user name or password, or no right to connect)"
    return f"{broker} refused the connection: {text}"


def host_name() -> str:
    return socket.gethostname().split(".")[0] or "host"
