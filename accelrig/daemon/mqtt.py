"""A device's samples published to an MQTT broker, spooled to disk while the broker is away.

The local segment files stay the record; publishing is a copy for the fleet.  The device
runner hands every block and gap record to its ``Publisher`` (``block``, ``gap``); each becomes
one message of the format in ``daemon.wire`` and a file in the device's spool directory
(``OUTPUT/NAME/spool/``).  One sender thread hands the oldest spool files to paho, at most
``WINDOW`` at a time, QoS 1; a file is deleted only when the broker's PUBACK for it arrives.
So while the broker is unreachable the spool grows on disk, and when it returns the backlog
goes out in order (paho re-sends the unacknowledged few itself; a duplicate is harmless, the
collector drops repeated sequence numbers).  A spool left by a stopped or killed daemon is
sent first at the next start.

The spool is bounded (``spool_megabytes``): past it the oldest waiting messages are dropped
and replaced by one gap message saying how many samples and blocks, so the receiver writes an
explicit gap record; the drops are counted in the device's status (``mqtt.dropped_samples``).
"""

from __future__ import annotations

import json
import os
import queue
import threading
import time
from collections import deque
from pathlib import Path

import numpy as np

from accelrig.daemon import wire
from accelrig.errors import AccelrigError

WINDOW = 32                  # messages handed to paho and not yet acknowledged
CLOSE_SECONDS = 1.0          # at stop: the most it may add to the daemon's 5 s (the rest stays spooled)
SPOOL_SUFFIX = ".msg"


class Spool:
    """Messages waiting for the broker, one file each, named so that order is name order."""

    def __init__(self, directory: Path, max_bytes: int):
        self.directory = directory
        self.max_bytes = max_bytes
        directory.mkdir(parents=True, exist_ok=True)
        for stale in directory.glob("*.tmp"):
            stale.unlink(missing_ok=True)
        self.waiting: deque[tuple[str, int]] = deque(
            (p.name, p.stat().st_size) for p in sorted(directory.glob("*" + SPOOL_SUFFIX)))
        self.inflight: dict[int, tuple[str, int]] = {}   # paho mid -> (name, size)
        self.bytes = sum(size for _, size in self.waiting)

    def __len__(self) -> int:
        return len(self.waiting) + len(self.inflight)   # (plus at most one being handed to paho)

    def add(self, name: str, payload: bytes) -> None:
        path = self.directory / name
        tmp = path.with_suffix(".tmp")
        with open(tmp, "wb") as fh:
            fh.write(payload)
        os.replace(tmp, path)        # a crash leaves a whole message or none
        self.waiting.append((name, len(payload)))
        self.bytes += len(payload)

    def read(self, name: str) -> bytes:
        return (self.directory / name).read_bytes()

    def done(self, name: str, size: int) -> None:
        (self.directory / name).unlink(missing_ok=True)
        self.bytes -= size

    def take_oldest(self) -> tuple[str, int]:
        name, size = self.waiting.popleft()
        return name, size


class Publisher:
    """One device's MQTT client: data (spooled, QoS 1), retained status and meta, last will."""

    def __init__(self, settings, site_device: str, spool_directory: Path, status_fn, log):
        self.settings = settings
        self.device = site_device
        self.log = log
        self.status_fn = status_fn              # () -> dict: the runner's status
        self.broker = wire.parse_broker(settings.broker)
        self.topics = {kind: wire.topic(settings.prefix, settings.site, site_device, kind)
                       for kind in ("data", "status", "meta", "profile")}
        self.host = wire.host_name()
        self.client_id = f"accelrig-{self.host}-{site_device}"[:128]
        self.spool = Spool(spool_directory, int(settings.spool_megabytes * 1e6))
        self.epoch = time.time_ns()
        self.seq = 0
        self.next_sample = 0
        self.scale = 0.0
        self.profile = ""
        self.counts = {"published": 0, "acknowledged": 0, "dropped_samples": 0, "dropped_messages": 0,
                       "spool_gaps": 0, "connects": 0, "reconnects": 0}
        self.connected = False
        self.error: str | None = None
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._client = None
        self._meta: dict | None = None
        self._profile_json = ""
        self._acks: queue.SimpleQueue[int] = queue.SimpleQueue()   # PUBACKs, from paho's thread
        self._handing: tuple[str, int] | None = None
        self._drop_logged = -1e9

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> None:
        password = wire.read_password(self.settings.password_file, self.settings.password_env)
        client = wire.make_client(self.client_id, self.broker, self.settings.username, password,
                                  self.settings.ca_file, clean=False,
                                  reconnect_max=self.settings.reconnect_max)
        client.max_inflight_messages_set(WINDOW + 8)
        client.max_queued_messages_set(0)
        client.will_set(self.topics["status"], json.dumps(self._offline()), qos=1, retain=True)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_publish = self._on_publish
        client.on_connect_fail = self._on_connect_fail
        self._client = client
        client.connect_async(self.broker.host, self.broker.port, keepalive=self.settings.keepalive)
        client.loop_start()
        self._thread = threading.Thread(target=self._run, name=f"accelrig mqtt {self.device}", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Send what can be sent within CLOSE_SECONDS, say "stopped", disconnect; the rest stays spooled."""
        deadline = time.monotonic() + CLOSE_SECONDS
        while len(self.spool) and self.connected and time.monotonic() < deadline:
            self._wake.set()
            time.sleep(0.02)
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(max(deadline - time.monotonic(), 0.1))
        client = self._client
        if client is None:
            return
        if self.connected:
            info = client.publish(self.topics["status"], json.dumps({**self._status(), "state": "stopped"}),
                                  qos=1, retain=True)
            try:
                info.wait_for_publish(max(deadline - time.monotonic(), 0.1))
            except (RuntimeError, ValueError):
                pass
        client.disconnect()
        client.loop_stop()
        self._retire_acknowledged()
        if len(self.spool):
            self.log(f"{self.device}: mqtt: {len(self.spool)} message(s) left in the spool; "
                     "they are sent at the next start")

    # ------------------------------------------------------------------ what the runner hands over
    def announce(self, meta: dict, scale: float, profile: str, profile_data: dict | None = None) -> None:
        """A connection of the device began: its description on the meta topic, the profile in use
        (the whole profile, JSON; empty without one) on the profile topic, both retained."""
        self.scale, self.profile = float(scale), profile
        self._meta = {**meta, "host": self.host, "site": self.settings.site,
                      "payload_version": wire.VERSION, "epoch": self.epoch}
        self._profile_json = json.dumps(profile_data, default=str) if profile_data is not None else ""
        if self._client is not None:
            self._publish_description(self._client)

    def _publish_description(self, client) -> None:
        client.publish(self.topics["meta"], json.dumps(self._meta, default=str), qos=1, retain=True)
        client.publish(self.topics["profile"], self._profile_json, qos=1, retain=True)

    def block(self, t_utc: np.ndarray, counts: np.ndarray) -> None:
        from accelrig.segments import to_ns

        t_ns = to_ns(t_utc)
        for start, stop in wire.split_block(t_ns):
            payload = wire.encode_data(self.epoch, self.seq, self.next_sample, t_ns[start:stop],
                                       counts[start:stop], self.scale, self.profile)
            self._enqueue(payload)
            self.next_sample += stop - start

    def gap(self, at_utc: float, samples: int, cause: str, seconds: float | None) -> None:
        from accelrig.segments import to_ns

        t0 = int(to_ns(np.asarray([at_utc]))[0])
        self._enqueue(wire.encode_gap(self.epoch, self.seq, self.next_sample, t0, self.scale, self.profile,
                                      samples, cause, seconds))

    def _enqueue(self, payload: bytes) -> None:
        name = f"{self.epoch:020d}-{self.seq:012d}{SPOOL_SUFFIX}"
        self.seq += 1
        with self._lock:
            try:
                self.spool.add(name, payload)
            except OSError as exc:   # the spool's disk is full: counted like a bound overflow
                message = wire.decode(payload)
                self._count_drop(message.samples, 1)
                self.error = f"spool not written ({exc.strerror})"
                return
            self._trim()
        self._wake.set()

    def _count_drop(self, samples: int, messages: int) -> None:
        self.counts["dropped_samples"] += samples
        self.counts["dropped_messages"] += messages

    def _trim(self) -> None:
        """Past the bound: drop the oldest waiting messages, replaced by one gap message (under the lock).

        The gap message takes the last dropped sequence number and says which it stands for
        (``first_seq``, ``from_sample``), so the receiver sees no hole beside it; dropping again
        while it still waits at the head folds it into the next one.
        """
        if self.spool.bytes <= self.spool.max_bytes or len(self.spool.waiting) < 2:
            return
        dropped, samples, data_samples, data_messages, unknown, causes = 0, 0, 0, 0, False, []
        first_seq = from_sample = t0 = t_end = last_name = None
        next_sample = 0
        while self.spool.bytes > self.spool.max_bytes * 0.9 and len(self.spool.waiting) > 1:
            name, size = self.spool.take_oldest()
            try:
                message = wire.decode(self.spool.read(name))
            except (OSError, AccelrigError):
                message = None
            self.spool.done(name, size)
            dropped += 1
            last_name = name
            if message is None:
                unknown = True
                continue
            g = message.gap or {}
            if first_seq is None:
                first_seq = g.get("first_seq", message.seq)
                from_sample = g.get("from_sample", message.first_sample)
                t0 = message.t0_ns
            if message.kind == wire.DATA:
                samples += message.samples
                data_samples += message.samples
                data_messages += 1
                next_sample = message.first_sample + message.samples
                t_end = int(message.t_ns[-1])
            else:   # a gap inside the dropped stretch (or an earlier spool gap): its samples join this one's
                unknown |= g.get("samples", -1) < 0
                samples += max(g.get("samples", 0), 0)
                next_sample = message.first_sample
                if not g.get("spool"):
                    causes.append(g.get("cause", "gap"))
        self.counts["spool_gaps"] += 1
        seq = int(last_name.split("-")[1].split(".")[0])   # the gap takes the last dropped number
        epoch = int(last_name.split("-")[0])
        cause = "broker unreachable and the spool full: the oldest blocks were dropped by the publisher"
        if causes:
            cause += f" (with gaps inside: {'; '.join(dict.fromkeys(causes))})"
        seconds = (t_end - t0) / 1e9 if t_end is not None and t0 is not None else None
        # first_sample of a gap message is the index of the next sample to come, as for the runner's gaps
        payload = wire.encode_gap(epoch, seq, next_sample, t0 or time.time_ns(), self.scale, self.profile,
                                  -1 if unknown else samples, cause, seconds,
                                  extra={"spool": True, "first_seq": first_seq if first_seq is not None else seq,
                                         "from_sample": from_sample if from_sample is not None else next_sample})
        (self.spool.directory / last_name).write_bytes(payload)
        self.spool.waiting.appendleft((last_name, len(payload)))
        self.spool.bytes += len(payload)
        self._count_drop(data_samples, data_messages)   # each dropped block counted once, folded gaps not again
        now = time.monotonic()
        if now - self._drop_logged > 60.0:
            self._drop_logged = now
            self.log(f"{self.device}: mqtt: spool over {self.settings.spool_megabytes:g} MB; dropping the oldest "
                     f"blocks (counted, and sent as one gap record); {self.counts['dropped_samples']} samples so far")

    # ------------------------------------------------------------------ sending
    def _run(self) -> None:
        next_status = 0.0
        while not self._stop.is_set():
            self._wake.wait(0.5)
            self._wake.clear()
            if not self.connected:
                continue
            self._send_waiting()
            now = time.monotonic()
            if now >= next_status:
                next_status = now + self.settings.status_seconds
                self._publish_status()

    def _send_waiting(self) -> None:
        """Hand the oldest waiting messages to paho, and retire the acknowledged ones.

        Only this thread touches ``inflight``: paho's callback merely queues the acknowledged
        ids (it runs holding paho's lock, and taking ours there could deadlock against a
        publish), and an id is looked up only after this thread has recorded it.
        """
        client = self._client
        while True:
            self._retire_acknowledged()
            with self._lock:
                if not self.connected or len(self.spool.inflight) >= WINDOW or not self.spool.waiting:
                    return
                name, size = self.spool.waiting.popleft()
                try:
                    payload = self.spool.read(name)
                except OSError as exc:
                    self.log(f"{self.device}: mqtt: spool file {name} unreadable ({exc.strerror}); skipped, "
                             "the collector records its sequence number as missing")
                    self.spool.done(name, size)
                    continue
                self._handing = (name, size)    # counted as spooled while paho has it
            info = client.publish(self.topics["data"], payload, qos=1)
            with self._lock:
                self._handing = None
                self.spool.inflight[info.mid] = (name, size)
                self.counts["published"] += 1

    def _retire_acknowledged(self) -> None:
        while True:
            try:
                mid = self._acks.get_nowait()
            except queue.Empty:
                return
            with self._lock:
                entry = self.spool.inflight.pop(mid, None)   # None: a status or meta message
                if entry is not None:
                    self.spool.done(*entry)
                    self.counts["acknowledged"] += 1

    def _publish_status(self) -> None:
        try:
            self._client.publish(self.topics["status"], json.dumps(self._status(), default=str), qos=1, retain=True)
        except Exception as exc:   # a status that cannot be built must not stop the data
            self.log(f"{self.device}: mqtt: status not published ({type(exc).__name__}: {exc})")

    def _status(self) -> dict:
        status = dict(self.status_fn())
        status.pop("url", None)   # may hold paths of the machine; the meta topic says what the fleet needs
        return {**status, "host": self.host, "site": self.settings.site, "device": self.device,
                "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), "mqtt": self.stats()}

    def stats(self) -> dict:
        with self._lock:
            spooled, spool_bytes = len(self.spool) + (self._handing is not None), self.spool.bytes
        return {"broker": str(self.broker), "connected": self.connected, "error": self.error,
                "spooled": spooled, "spool_bytes": spool_bytes, **self.counts}

    def _offline(self) -> dict:
        return {"state": "offline", "host": self.host, "site": self.settings.site, "device": self.device,
                "online_since": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}

    # ------------------------------------------------------------------ paho callbacks (its thread)
    def _on_connect(self, client, userdata, flags, reason, properties=None) -> None:
        if getattr(reason, "is_failure", False):
            error = wire.connect_error(self.broker, reason)
            if error != self.error:
                self.log(f"{self.device}: mqtt: {error}")
            self.error = error
            return
        self.connected, self.error = True, None
        with self._lock:
            self.counts["reconnects"] += self.counts["connects"] > 0   # every connection after the first
            self.counts["connects"] += 1
        self.log(f"{self.device}: mqtt: connected to {self.broker} as {self.client_id}"
                 f"{f', {len(self.spool)} spooled message(s) to send' if len(self.spool) else ''}")
        if self._meta is not None:
            self._publish_description(client)
        self._wake.set()

    def _on_connect_fail(self, client, userdata) -> None:
        error = f"cannot connect to {self.broker} (unreachable, or TLS refused); retrying, blocks are spooled"
        if error != self.error:
            self.log(f"{self.device}: mqtt: {error}")
        self.error = error

    def _on_disconnect(self, client, userdata, flags, reason, properties=None) -> None:
        if self.connected and not self._stop.is_set():
            self.log(f"{self.device}: mqtt: lost {self.broker} ({reason}); spooling to disk until it returns")
        self.connected = False
        if not self._stop.is_set():
            self.error = f"disconnected: {reason}"

    def _on_publish(self, client, userdata, mid, reason=None, properties=None) -> None:
        self._acks.put(mid)
        self._wake.set()
