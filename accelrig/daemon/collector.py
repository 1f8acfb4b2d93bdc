"""``accelrig collect``: the fleet's blocks from an MQTT broker into the same segment files the daemons write.

One persistent MQTT session (QoS 1: the broker keeps what arrives while the collector is away)
subscribes to ``PREFIX/SITE/+/data`` and ``.../meta`` (SITE ``+``: the whole fleet).  Each device
gets ``OUTPUT/SITE/DEVICE/`` with a SegmentWriter, so every accelrig reader takes the result.

Per device the collector follows the publisher's sequence numbers (``daemon.wire``):

* a number already seen is a re-sent block (the publisher re-sends what it has no PUBACK for):
  dropped, counted as a duplicate;
* a jump is a stretch that never arrived: written as a gap record holding exactly the samples
  missing (from the blocks' sample indices), cause "not received";
* gap messages (the daemon's own gap records, and the publisher's spool overflow) become gap
  records as they are.

The place reached per device (epoch, next sequence number, next sample, last time) is kept in
``OUTPUT/SITE/DEVICE/collector.json``, so a restarted collector still recognises repeats.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from accelrig.daemon import wire
from accelrig.errors import AccelrigError, DataError

STATE_FILE = "collector.json"
SAVE_SECONDS = 5.0


def log(line: str) -> None:
    stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    sys.stderr.write(f"{stamp} accelrig collect: {line}\n")
    sys.stderr.flush()


@dataclass
class Stream:
    """One device's place in its publisher's sequence, and its writer."""

    site: str
    device: str
    directory: Path
    epoch: int | None = None
    next_seq: int = 0
    next_sample: int = 0
    last_ns: int | None = None
    meta: dict = field(default_factory=dict)
    writer: object = None
    counts: dict = field(default_factory=lambda: {"messages": 0, "samples": 0, "duplicates": 0, "gaps": 0,
                                                  "not_received": 0, "late": 0})

    def state(self) -> dict:
        return {"epoch": self.epoch, "next_seq": self.next_seq, "next_sample": self.next_sample,
                "last_ns": self.last_ns}


class Collector:
    def __init__(self, broker: str, output: Path, *, site: str | None = None, prefix: str = wire.DEFAULT_PREFIX,
                 username: str | None = None, password: str | None = None, ca_file: str | None = None,
                 client_id: str | None = None, segment_seconds: float = 3600.0, log=log):
        self.broker = wire.parse_broker(broker)
        self.output = Path(output)
        self.site = site or "+"
        self.prefix = prefix
        self.username, self.password, self.ca_file = username, password, ca_file
        self.client_id = client_id or f"accelrig-collect-{wire.host_name()}-{site or 'all'}"
        self.segment_seconds = segment_seconds
        self.log = log
        self.streams: dict[tuple[str, str], Stream] = {}
        self._lock = threading.Lock()
        self._connected = threading.Event()
        self._refused: str | None = None
        self._client = None

    # ------------------------------------------------------------------ running
    def connect(self, timeout: float = 10.0) -> None:
        """Connect and subscribe; BrokerError in one line when refused or unreachable within ``timeout``."""
        self.output.mkdir(parents=True, exist_ok=True)
        client = wire.make_client(self.client_id, self.broker, self.username, self.password, self.ca_file,
                                  clean=False)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        self._client = client
        try:
            client.connect(self.broker.host, self.broker.port, keepalive=30)
        except OSError as exc:
            raise wire.BrokerError(f"{self.broker}: cannot connect ({exc.strerror or exc})",
                                   "check the broker's address and that it is running") from None
        client.loop_start()
        deadline = time.monotonic() + timeout
        while not self._connected.is_set() and self._refused is None and time.monotonic() < deadline:
            time.sleep(0.02)
        if self._refused is not None or not self._connected.is_set():
            client.loop_stop()
            client.disconnect()
            raise wire.BrokerError(self._refused or f"{self.broker}: no answer within {timeout:g} s")

    def run(self, stop: threading.Event) -> None:
        """Until ``stop`` is set: collect (paho's thread writes), saving each device's place now and then."""
        while not stop.wait(SAVE_SECONDS):
            self._save_all()

    def close(self) -> None:
        client = self._client
        if client is not None:
            self._connected.clear()   # our own disconnect: not a lost broker to reconnect to
            client.disconnect()
            client.loop_stop()
        with self._lock:
            for stream in self.streams.values():
                self._close_writer(stream)
                self._save(stream)

    def summary(self) -> list[str]:
        return [f"{s.site}/{s.device}: {s.counts['samples']} samples in {s.counts['messages']} messages, "
                f"{s.counts['gaps']} gap records ({s.counts['not_received']} not received), "
                f"{s.counts['duplicates']} duplicates dropped" for s in self.streams.values()]

    # ------------------------------------------------------------------ paho callbacks
    def _on_connect(self, client, userdata, flags, reason, properties=None) -> None:
        if getattr(reason, "is_failure", False):
            self._refused = wire.connect_error(self.broker, reason)
            if self._connected.is_set():
                self.log(self._refused)
            return
        first = not self._connected.is_set()
        self._connected.set()
        # subscribed on every connect: a broker that lost our session (no persistence) still sends
        client.subscribe([(wire.topic(self.prefix, self.site, "+", "data"), 1),
                          (wire.topic(self.prefix, self.site, "+", "meta"), 1)])
        self.log(f"{'connected to' if first else 'reconnected to'} {self.broker} as {self.client_id}, "
                 f"{self.prefix}/{self.site}/+/data into {self.output}")

    def _on_disconnect(self, client, userdata, flags, reason, properties=None) -> None:
        if self._connected.is_set():
            self.log(f"lost {self.broker} ({reason}); reconnecting (the broker keeps our messages meanwhile)")

    def _on_message(self, client, userdata, message) -> None:
        where = wire.split_topic(self.prefix, message.topic)
        if where is None:
            return
        site, device, kind = where
        try:
            with self._lock:
                stream = self._stream(site, device)
                if kind == "meta":
                    stream.meta = json.loads(message.payload)
                elif kind == "data":
                    self._take(stream, wire.decode(message.payload))
        except Exception as exc:   # noqa: BLE001 - an exception here would stop paho's thread, and all collection
            # a malformed message, or a segment that cannot be written (disk full), must not stop
            # the fleet's collection: it is said, and its sequence number becomes a "not received"
            # gap record when a later message can be written
            if not isinstance(exc, AccelrigError | ValueError):
                import traceback

                traceback.print_exc()
            self.log(f"{site}/{device}: {kind} message skipped: {exc}")

    # ------------------------------------------------------------------ one device
    def _stream(self, site: str, device: str) -> Stream:
        key = (site, device)
        stream = self.streams.get(key)
        if stream is None:
            directory = self.output / site / device
            stream = Stream(site, device, directory)
            try:
                saved = json.loads((directory / STATE_FILE).read_text())
                stream.epoch, stream.next_seq = saved["epoch"], saved["next_seq"]
                stream.next_sample, stream.last_ns = saved["next_sample"], saved["last_ns"]
            except (OSError, ValueError, KeyError):
                pass
            self.streams[key] = stream
            self.log(f"{site}/{device}: new device, into {directory}")
        return stream

    def _take(self, stream: Stream, m: wire.Message) -> None:
        stream.counts["messages"] += 1
        if stream.epoch is not None and m.epoch < stream.epoch:
            stream.counts["late"] += 1     # an earlier run's message after a later run's: its place is gone
            self.log(f"{stream.site}/{stream.device}: a message of an earlier publisher run arrived late; dropped "
                     f"(run {m.epoch}, number {m.seq})")
            return
        if stream.epoch is None or m.epoch > stream.epoch:
            stream.epoch, stream.next_seq, stream.next_sample = m.epoch, 0, 0
        if m.seq < stream.next_seq:
            stream.counts["duplicates"] += 1
            return
        g = m.gap or {}
        first_seq = int(g.get("first_seq", m.seq))       # a spool gap stands for first_seq..seq
        if first_seq > stream.next_seq:
            self._not_received(stream, m, first_seq, int(g.get("from_sample", m.first_sample)))
        if m.kind == wire.DATA:
            self._write(stream, m)
            stream.next_sample = m.first_sample + m.samples
        else:
            g = m.gap
            self._writer(stream, m.scale).gap(m.t0_ns, int(g.get("samples", -1)), str(g.get("cause", "gap")),
                                              g.get("seconds"))
            stream.counts["gaps"] += 1
            stream.next_sample = m.first_sample
        stream.next_seq = m.seq + 1

    def _not_received(self, stream: Stream, m: wire.Message, first_seq: int, from_sample: int) -> None:
        missing = from_sample - stream.next_sample
        seconds = (m.t0_ns - stream.last_ns) / 1e9 if stream.last_ns is not None else None
        cause = (f"not received: messages {stream.next_seq}..{first_seq - 1} of the publisher's run never reached the "
                 "collector")
        self._writer(stream, m.scale).gap(m.t0_ns, missing if missing >= 0 else -1, cause, seconds)
        stream.counts["gaps"] += 1
        stream.counts["not_received"] += 1
        self.log(f"{stream.site}/{stream.device}: {cause} ({missing} samples); gap record written")

    def _write(self, stream: Stream, m: wire.Message) -> None:
        t_ns, counts = m.t_ns, m.counts
        if stream.last_ns is not None and t_ns[0] <= stream.last_ns:
            keep = t_ns > stream.last_ns    # already stored (a repeat the state file did not know of)
            stream.counts["duplicates"] += int((~keep).sum() > 0)
            t_ns, counts = t_ns[keep], counts[keep]
            if not t_ns.size:
                return
        writer = self._writer(stream, m.scale)
        writer.write(t_ns, counts)
        stream.last_ns = int(t_ns[-1])
        stream.counts["samples"] += int(t_ns.size)

    def _writer(self, stream: Stream, scale: float):
        from accelrig.segments import SegmentWriter

        if stream.writer is not None and stream.writer.scale != float(scale):
            self._close_writer(stream)      # the range changed: a segment holds one scale
        if stream.writer is None:
            meta = {**stream.meta, "name": stream.device, "site": stream.site, "time_base": "utc",
                    "collected": {"broker": str(self.broker), "client_id": self.client_id}}
            stream.writer = SegmentWriter(stream.directory, stem=stream.device, meta=meta, scale=scale,
                                          segment_seconds=self.segment_seconds)
        return stream.writer

    def _close_writer(self, stream: Stream) -> None:
        writer, stream.writer = stream.writer, None
        if writer is not None:
            try:
                writer.close()
            except (AccelrigError, DataError) as exc:
                self.log(f"{stream.site}/{stream.device}: closing the segment: {exc}")

    def _save(self, stream: Stream) -> None:
        from accelrig.files import atomic_write

        if not stream.directory.is_dir():
            return
        try:
            text = json.dumps(stream.state()) + "\n"
            atomic_write(stream.directory / STATE_FILE, lambda fh: fh.write(text), text=True)
        except (OSError, AccelrigError) as exc:
            self.log(f"{stream.site}/{stream.device}: place not saved ({exc})")

    def _save_all(self) -> None:
        with self._lock:
            for stream in self.streams.values():
                self._save(stream)
