"""One device under the daemon's care: connect, flash, stream to segments, reconnect, account for every sample.

A DeviceRunner owns one thread that keeps its device recorded:

* connect: open the driver (through ``UtcDriver``, which puts every sample on
  absolute UTC time), write a profile a URL names (``profile=PATH``) or the
  configured profile's offsets (``flash: true``) on **every** connect (offset
  registers are volatile), choose the profile (store, path or none), start the
  Session's pump with one lossless reader;
* stream: every ``POLL`` seconds the connection's Recorder (the one path from
  chunks and their gaps to writer calls, shared with ``accelrig record``)
  hands what arrived to this runner's ``write`` and ``gap``, which add the
  daemon's care (calibrated channels when asked, the publisher, a full disk,
  the journal) around the connection's SegmentWriter;
* faults: a device error, a stall (no data for ``stall_seconds``) or a failed
  connect closes the connection's writer and reconnects after an exponential
  backoff; the time without data becomes a gap record with its cause and
  duration at the start of the next connection's segments.  Gaps the driver
  reports (FIFO overflow, corrupt or lost frames) become gap records where
  they happened.  A full disk drops samples, counted, until a write succeeds
  again, and then a "disk full" gap record says how many and how long.
* a profile this device needs that cannot be used (none stored for its
  identity, a file that does not load, one made for another device, chip or
  range): the raw counts are recorded anyway, in state "recording raw", with
  the reason in the status, the log, the journal and every segment's
  metadata, so nothing is lost and ``accelrig profile apply`` calibrates the
  data later (``without_profile: stop`` stops the device instead).  A reload
  restarts such a device once its profile is there.  Other problems no retry
  can fix (a URL no driver takes) stop this device only, with the field named.

Accounting, kept in ``counts`` and written to the device's journal when it
stops: delivered = written + dropped (each dropped sample in a "disk full"
gap record); missing = the samples the device reported lost (in gap records
of known size).

The journal (``OUTPUT/NAME/journal.jsonl``) has one JSON line per event:
connect (device, profile, flash, time base), gap, disconnect, stop.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from accelrig.acquisition.block import Block
from accelrig.acquisition.driver import DeviceInfo, Driver, driver_for
from accelrig.acquisition.recorder import Recorder, stream_meta
from accelrig.acquisition.session import Session, State
from accelrig.daemon.clock import UtcClock
from accelrig.daemon.config import ConfigError, DaemonConfig, DeviceConfig
from accelrig.errors import AccelrigError, DeviceStalled, ProfileError, StorageError, StorageFull
from accelrig.profiles.apply import RECORDED_CALIBRATED_CHANNELS, RECORDED_UNCERTAINTY_CHANNELS

POLL = 0.2                 # s between writes of what arrived
DISK_RETRY = 2.0           # s between write attempts while the disk is full
CALIBRATED_CHANNELS = RECORDED_CALIBRATED_CHANNELS     # the names `profile apply` knows to leave out
UNCERTAINTY_CHANNELS = RECORDED_UNCERTAINTY_CHANNELS
RECORDING_STATES = ("streaming", "recording raw")   # samples are being written ("recording raw": without
                                                    # the profile the configuration asks for)


def utc_text(seconds: float | None) -> str | None:
    if seconds is None:
        return None
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(seconds)) + f".{int((seconds % 1) * 1e6):06d}Z"


class UtcDriver(Driver):
    """The device's driver with every block's times mapped to UTC seconds (``clock.UtcClock``).

    A new UtcClock per open: each connection is anchored afresh.
    """

    def __init__(self, inner: Driver):
        super().__init__(inner.url)
        self.inner = inner
        self.scheme = inner.scheme
        self.clock: UtcClock | None = None

    def open(self) -> DeviceInfo:
        info = self.inner.open()
        self.clock = UtcClock(info.nominal_rate)
        return info

    def read(self, timeout: float = 0.1) -> list[Block]:
        blocks = self.inner.read(timeout)
        if not blocks:
            return blocks
        arrival = time.monotonic()   # every block of this read had arrived by now
        return [replace(b, t=self.clock.map(b.t, arrival, int(b.gap_before))) for b in blocks]

    def close(self) -> None:
        self.inner.close()

    @property
    def at_end(self) -> bool:
        return self.inner.at_end

    @property
    def info(self) -> DeviceInfo | None:
        return self.inner.info

    @info.setter
    def info(self, value) -> None:
        if hasattr(self, "inner"):
            self.inner.info = value

    @property
    def can_flash(self) -> bool:
        return self.inner.can_flash

    def plan_flash(self, correction, profile_id):
        return self.inner.plan_flash(correction, profile_id)

    def flash(self, plan):
        return self.inner.flash(plan)


@dataclass
class Counts:
    """What happened to the samples of one device, over the daemon's life (all connections)."""

    delivered: int = 0        # samples the driver delivered
    written: int = 0          # samples in segments
    dropped: int = 0          # delivered but not written (disk full), each in a gap record
    missing: int = 0          # samples the device reported lost (known sizes), in gap records
    gaps: int = 0             # gap records written
    connects: int = 0
    failed_connects: int = 0


@dataclass
class PendingGap:
    """A stretch without samples, written as a record before the next sample."""

    cause: str
    since_utc: float | None       # UTC of the last sample before it (None: no sample yet)
    samples: int = -1             # -1: unknown (the device was not there to count)
    extra: dict = field(default_factory=dict)


# a restarted device whose previous runner has not stopped yet (reload): it must not write beside it
WAITING_FOR_PREVIOUS = ("waiting for this device's previous run to stop (a driver call hangs in it): "
                        "starting when it returns")


class DeviceRunner:
    def __init__(self, device: DeviceConfig, config: DaemonConfig, log, finisher=None):
        self.device = device
        self.config = config
        self.log = log                       # log(line): one status/event line for the operator
        self.finisher = finisher             # segments.Finisher shared by the daemon's devices (None: this thread)
        self.directory = Path(config.output) / device.name
        self.counts = Counts()
        self.state = "starting"
        self.last_error: str | None = None
        self.profile_note = "none"
        self.profile_problem: str | None = None   # why the profile it needs is not used: recording raw
        self._problems: list[str] = []            # this connection's unusable profiles, with their fixes
        self._problem_sources: set[str] = set()   # where they were named: "url" (profile=PATH), "profile"
        self.info: DeviceInfo | None = None
        self.session: Session | None = None
        self.writer = None
        self.measured_rate: float | None = None
        self.delivered_rate = 0.0
        self.last_sample_utc: float | None = None
        self.last_data = time.monotonic()    # monotonic time of the last sample received
        self.heartbeat = time.monotonic()    # the loop's last turn (the watchdog checks it)
        self._stop = threading.Event()
        self.stop_reason = "the daemon was stopped"
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._pending: PendingGap | None = None
        self._disk_full: dict | None = None  # {"since": utc, "samples": n, "next_try": monotonic}
        self._gap_unwritten: dict | None = None  # a disk-full gap record the segment refused: retried
        self._profile = None
        self._bytes_closed = 0
        self._segments_closed = 0
        self.publisher = None                # daemon.mqtt.Publisher when the config has an mqtt section

    # ------------------------------------------------------------------ lifecycle
    def start(self, after: DeviceRunner | None = None) -> None:
        """Start the device's thread.  ``after``: this device's previous runner, still stopping (a driver call
        hangs in it): this one waits, state "waiting", until that one has returned (its segments closed, the
        directory's lock released, its stop in the journal) before it touches the directory or the device."""
        if after is None:
            self._prepare()
        target, args = (self._run, ()) if after is None else (self._run_after, (after,))
        self._thread = threading.Thread(target=target, args=args, name=f"accelrig daemon {self.device.name}",
                                        daemon=True)
        self._thread.start()

    def _prepare(self) -> None:
        self.directory.mkdir(parents=True, exist_ok=True)
        self._pending = self._since_last_run()
        if self.config.mqtt is not None:
            self._start_publisher()

    def _run_after(self, previous: DeviceRunner) -> None:
        self._set("waiting", WAITING_FOR_PREVIOUS)
        while not previous.join(0.5):
            self.heartbeat = time.monotonic()   # waiting is the loop turning, for the watchdog
            if self._stop.is_set():   # stopped again before it began: nothing was opened, nothing to close
                self._set("stopped", WAITING_FOR_PREVIOUS)
                return
        self.log(f"{self.device.name}: the previous run has stopped; starting")
        try:
            self._prepare()
        except Exception as exc:
            self._fail(f"cannot start after the previous run: {exc}")
            return
        self._run()

    def _since_last_run(self) -> PendingGap | None:
        """Finish what a crash left open, and the gap between the last run's last sample and this run.

        A run that stopped says when and why in its journal's last "stop" event;
        one that was killed left an open segment whose last complete block says when.
        """
        from accelrig.errors import DataError
        from accelrig.segments import OPEN_SUFFIX, recover, scan

        last_ns = None
        for path in sorted(self.directory.glob("*" + OPEN_SUFFIX)):
            try:
                scanned = scan(path)
            except DataError:
                continue    # recover() says what is wrong with it
            if scanned.last_ns is not None:
                last_ns = max(last_ns or scanned.last_ns, scanned.last_ns)
        reports = recover(self.directory)   # segments a crash (kill -9, power cut) left open
        for report in reports:
            self.log(f"{self.device.name}: {report}")
            self._journal("recovered", report=str(report), samples=report.samples,
                          lost_samples=report.lost_samples, lost_bytes=report.lost_bytes)
        if reports:
            since = last_ns / 1e9 if last_ns is not None else None
            return PendingGap("not recording: the previous run ended without stopping (killed or crashed)", since)
        last = self._last_journal_event()
        if last is not None and last.get("event") == "stop" and last.get("last_sample_utc") is not None:
            return PendingGap(f"not recording: {last.get('reason', 'stopped')}", float(last["last_sample_utc"]))
        if last is not None:
            return PendingGap("not recording: the previous run ended without stopping (killed or crashed)", None)
        return None

    def _start_publisher(self) -> None:
        """The device's MQTT publisher: a copy of every block and gap for the fleet (the files stay the record)."""
        from accelrig.daemon.mqtt import Publisher

        try:
            publisher = Publisher(self.config.mqtt, self.device.name, self.directory / "spool", self.status, self.log)
            publisher.start()
        except AccelrigError as exc:   # checked at start; a password file removed since, on reload
            self.log(f"{self.device.name}: mqtt: not publishing: {exc}")
            self._journal("mqtt_failed", error=str(exc))
            return
        self.publisher = publisher

    def _last_journal_event(self) -> dict | None:
        path = self.directory / "journal.jsonl"
        try:
            with open(path, "rb") as fh:
                fh.seek(max(fh.seek(0, 2) - 65536, 0))
                lines = fh.read().splitlines()
        except FileNotFoundError:
            return None
        for line in reversed(lines):
            try:
                return json.loads(line)
            except ValueError:
                continue   # a line torn by a crash
        return None
    def stop(self, reason: str = "the daemon was stopped") -> None:
        """Ask the thread to flush and stop (returns at once; ``join`` waits); ``reason`` goes to the journal."""
        self.stop_reason = reason
        self._stop.set()

    def join(self, timeout: float | None = None) -> bool:
        if self._thread is not None:
            self._thread.join(timeout)
            return not self._thread.is_alive()
        return True

    @property
    def healthy(self) -> bool:
        """The loop turned recently (a hung write or driver call makes it false)."""
        return self.state in ("failed", "ended", "stopped") or time.monotonic() - self.heartbeat < 10 * POLL + 5.0

    # ------------------------------------------------------------------ the loop
    def _run(self) -> None:
        backoff = self.config.reconnect_initial
        try:
            while not self._stop.is_set():
                self.heartbeat = time.monotonic()
                streamed = False
                try:
                    self._connect()
                except ConfigError as exc:
                    self._fail(str(exc))
                    return
                except AccelrigError as exc:
                    self.counts.failed_connects += 1
                    self._set("waiting", str(exc))
                    if self._pending is None:
                        self._pending = PendingGap(f"connect failed: {exc}", self.last_sample_utc)
                    self.log(f"{self.device.name}: cannot connect ({exc}); next try in {backoff:g} s")
                    self._journal("connect_failed", error=str(exc), retry_in=backoff)
                    self._wait(backoff)
                    backoff = min(backoff * 2, self.config.reconnect_max)
                    continue
                except Exception as exc:
                    reason = self._internal_error(exc)
                else:
                    try:
                        streamed, reason = self._stream()
                    except Exception as exc:
                        reason = self._internal_error(exc)
                if streamed:
                    backoff = self.config.reconnect_initial
                if reason is None:          # stopped by the daemon, or a finite source ended
                    return
                self._set("waiting", reason)
                self.log(f"{self.device.name}: {reason}; reconnecting in {backoff:g} s")
                self._wait(backoff)
                if not streamed:
                    backoff = min(backoff * 2, self.config.reconnect_max)
        finally:
            self._finish()

    def _internal_error(self, exc: Exception) -> str:
        """A bug met while connecting or streaming: shown in full, recorded, and the device reconnected
        (a daemon that runs for weeks must not lose a device to one bad block)."""
        import traceback

        traceback.print_exc()
        reason = f"internal error: {type(exc).__name__}: {exc}"
        self._journal("internal_error", error=reason, traceback=traceback.format_exc())
        if self._pending is None:
            self._pending = PendingGap(reason, self.last_sample_utc)
        return reason

    def _wait(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while not self._stop.is_set() and time.monotonic() < end:
            self.heartbeat = time.monotonic()
            self._stop.wait(min(0.5, max(end - time.monotonic(), 0.0)))

    def _set(self, state: str, error: str | None = None) -> None:
        with self._lock:
            self.state = state
            self.last_error = error

    def _fail(self, message: str) -> None:
        self._set("failed", message)
        self.log(f"{self.device.name}: stopped: {message}")
        self._journal("failed", error=message)

    # ------------------------------------------------------------------ connecting
    def _connect(self) -> None:
        from accelrig.profiles.flash import flash_url_profile

        self._set("connecting", self.last_error)
        try:
            driver = UtcDriver(self._driver())
        except AccelrigError as exc:
            raise ConfigError(f"{self.device.field('url')}: {exc}") from None
        session = Session(driver=driver, buffer_seconds=30.0)
        try:
            info = session.open()
            self.profile_problem, self._problems, self._problem_sources = None, [], set()
            try:
                flash_url_profile(driver)        # a URL's profile=PATH, as everywhere else
            except ProfileError as exc:          # not written: the chip keeps its factory offsets
                self._without_profile(f"the URL's profile=PATH was not flashed: {exc.message}",
                                      "give the URL a profile made for this device", "url")
            self._profile = self._choose_profile(info)
            flashed = self._flash(driver) if self.device.flash and self._profile is not None else None
            self._open_writer(info, driver.clock, flashed)
            recorder = Recorder(info, session.reader(from_oldest=True, lossless=True), session, writer=self,
                                utc_times=True)
            session.start()
        except ProfileError as exc:
            session.stop()
            self._close_writer()
            raise ConfigError(f"{self.device.field('profile')}: {exc}") from None
        except BaseException:
            session.stop()
            self._close_writer()
            raise
        self.session, self.info, self._recorder = session, info, recorder
        self.counts.connects += 1
        self._journal("connect", connection=self.counts.connects, url=info.url, identity=info.identity,
                      nominal_rate=info.nominal_rate, profile=self._profile_reference(), flashed=flashed,
                      hardware_bias_removed=info.hardware_bias_removed, recording_raw=self.profile_problem)
        self.last_data = time.monotonic()
        self._set(*self._streaming_state())
        self.log(f"{self.device.name}: connected to {info.url} ({info.chip} {info.identity}, "
                 f"{info.nominal_rate:g} Hz), profile {self.profile_note}")
        if self.profile_problem is not None:
            self.log(f"{self.device.name}: WARNING: {self.profile_problem}")

    def _driver(self):
        """The device's driver, told this device's stall limit (``stall_limit``) when it watches for stalls
        itself (serial, BLE): the driver and the daemon then cut a silent device at the same moment, and
        both record it as ``stalled: ...``."""
        from accelrig.acquisition.url import DeviceURL

        url = DeviceURL.parse(self.device.url)
        driver = driver_for(url)
        if "stall" not in url.params and "stall" in (driver.known_options() or ()):
            # url.raw stays as configured; the driver takes at most an hour
            url.params["stall"] = repr(min(float(self.config.stall_seconds), 3600.0))
        return driver

    @property
    def stall_limit(self) -> float:
        """Seconds without data after which this connected device counts as stalled: the daemon's
        ``stall_seconds``, or the device URL's own ``stall=S`` (serial, BLE) when it gives one."""
        from accelrig.acquisition.url import DeviceURL

        own = DeviceURL.parse(self.device.url).get_str("stall")
        try:
            return float(own) if own is not None else float(self.config.stall_seconds)
        except ValueError:   # the driver refuses it, naming the option, when it opens
            return float(self.config.stall_seconds)

    def _streaming_state(self) -> tuple[str, str | None]:
        """(state, why) while samples are written: "recording raw" says the profile it needs is not used."""
        if self.profile_problem is not None:
            return "recording raw", self.profile_problem
        return "streaming", None

    def _without_profile(self, problem: str, fix: str, source: str) -> None:
        """The profile this device needs (``source``: "url" for the URL's profile=PATH, "profile" for its
        field) cannot be used: record the raw counts anyway, saying so everywhere (``without_profile:
        raw``), or stop the device (``stop``: the ProfileError)."""
        if self.device.without_profile == "stop":
            raise ProfileError(problem, fix)
        self._problems.append(f"{problem}; {fix}")
        self._problem_sources.add(source)
        gains = [gain for gain, wanted in (("get calibrated channels", self.device.output == "calibrated"),
                                           ("flash its offsets", self.device.flash)) if wanted]
        self.profile_problem = (f"recording raw: {'; '.join(self._problems)}, then reload the daemon (SIGHUP or "
                                f"systemctl reload){' to ' + ' and '.join(gains) if gains else ''}; "
                                "`accelrig profile apply` calibrates what was recorded raw")
        self._journal("recording_raw", problem=problem)

    def _choose_profile(self, info: DeviceInfo):
        """The profile this connection uses (or None), checked against the device."""
        device = self.device
        try:
            profile, warnings = self._find_profile(info)
        except ProfileError as exc:
            from accelrig.profiles.store import UnusableProfiles

            self.profile_note = "none"
            # its stored files cannot be read: repairing them is the fix, not a new calibration
            fix = (exc.hint if isinstance(exc, UnusableProfiles) else
                   "calibrate the device and file its profile (accelrig profile add PROFILE)"
                   if device.profile == "store" else
                   f"give {device.field('profile')} a profile made for this device")
            self._without_profile(exc.message, fix, "profile")
            return None
        for warning in warnings:
            self.log(f"{device.name}: {warning}")
        if profile is not None:
            self.profile_note = str(profile.path)
        elif device.profile == "store":
            self.profile_note = f"none (no stored profile for {info.identity!r})"
        else:
            self.profile_note = "none"
        return profile

    def _find_profile(self, info: DeviceInfo):
        """(profile, warnings) as configured for this device: (None, []) when it is to use none (``profile:
        none``, or a raw device with none stored); ProfileError when the one it needs cannot be used."""
        from accelrig.profiles.apply import check_compatible
        from accelrig.profiles.io import load_profile
        from accelrig.profiles.store import ProfileStore, UnusableProfiles

        device = self.device
        if device.profile == "none":
            return None, []
        if device.profile == "store":
            store = ProfileStore(self.config.profile_store)
            try:
                choice = store.choose(info.identity, data=info.to_dict(), units="counts")
            except ProfileError as exc:
                if device.output == "raw" and not device.flash:
                    return None, [b.warning() for b in store.scan(info.identity)[1]]
                if isinstance(exc, UnusableProfiles):
                    raise
                held = store.identities()
                raise ProfileError(f"no profile for {info.identity!r} in the store {store.root} "
                                   + (f"(it holds {', '.join(held)})" if held else "(it is empty)")) from None
            # which profile was chosen and which newer ones were passed over, and why (store.choose)
            profile, warnings = choice.stored.profile, list(choice.notes) + list(choice.warnings)
        else:
            profile, warnings = load_profile(device.profile_path), []
        return profile, warnings + [f"profile: {w}" for w in check_compatible(
            profile, info.to_dict(), "counts", force_hint="name the profile made for this device in the config")]

    def profile_now_usable(self) -> bool:
        """Recording raw for want of a profile that can be used now (a reload restarts the device for it)."""
        from accelrig.acquisition.url import DeviceURL
        from accelrig.profiles.apply import check_compatible
        from accelrig.profiles.io import load_profile

        info = self.info
        if self.profile_problem is None or info is None:
            return False
        try:
            if "url" in self._problem_sources:
                path = DeviceURL.parse(self.device.url).get_str("profile")
                check_compatible(load_profile(path), info.to_dict(), "counts")
            if "profile" in self._problem_sources:
                self._find_profile(info)
        except ProfileError:
            return False
        return True

    def _flash(self, driver) -> dict:
        """Write the profile's offsets to the chip (every connect: the registers are volatile)."""
        from accelrig.profiles.flash import plan_flash

        report = driver.flash(plan_flash(driver, self._profile))
        if not report.verified:
            raise AccelrigError(f"flashing the offsets was not verified: {'; '.join(report.notes)}")
        driver.info.offsets_applied = report.residual
        return {"verified": report.verified, "residual": report.residual}

    def _profile_reference(self) -> dict | None:
        p = self._profile
        if p is None:
            return None
        return {"path": str(p.path) if p.path else None, "identity": p.identity,
                "created": p.data["provenance"]["created"], "procedure": p.procedure, "method": p.method}

    # ------------------------------------------------------------------ writing
    @property
    def _calibrating(self) -> bool:
        """Calibrated channels are written: asked for, and the profile is there."""
        return self.device.output == "calibrated" and self._profile is not None

    def _channel_names(self, info: DeviceInfo) -> tuple[str, ...]:
        names = tuple(info.channels)
        if self._calibrating:
            names += CALIBRATED_CHANNELS + (UNCERTAINTY_CHANNELS if self.device.uncertainty else ())
        return names

    def _open_writer(self, info: DeviceInfo, clock: UtcClock, flashed: dict | None) -> None:
        from accelrig.segments import SegmentWriter

        # the device stated as every recording states it (identity, chip, range, scale, flashed
        # offsets at the top level), so `profile apply` and the calibrate commands read daemon
        # output like any recording; the driver's other facts under "device_facts"
        meta = stream_meta(info)
        meta.update({
            "device_facts": {k: v for k, v in info.to_dict()["extra"].items() if k not in meta},
            "name": self.device.name,
            "nominal_rate": info.nominal_rate,
            "connection": self.counts.connects + 1,
            "time_base": "utc",
            "clock": clock.describe(),
            "profile": self._profile_reference(),
            "output": self.device.output,
            "flashed": flashed,
        })
        if self.profile_problem is not None:
            # the configuration asked for a profile this segment does without: its raw counts are complete,
            # and `accelrig profile apply PROFILE` (device checked by identity, chip, range) calibrates them
            meta["recording_raw"] = self.profile_problem
        if self._calibrating:
            meta["calibrated_channels"] = {
                "cal_x, cal_y, cal_z": "calibrated acceleration, m/s^2: C @ (counts x scale - b) of the profile",
                **({"u_x, u_y, u_z": "standard uncertainty of each calibrated axis, m/s^2"}
                   if self.device.uncertainty else {}),
            }
        self.writer = SegmentWriter(
            self.directory, stem=self.device.name, meta=meta, scale=info.scale, channels=self._channel_names(info),
            segment_seconds=self.config.segment_seconds,
            segment_bytes=int(self.config.segment_megabytes * 1e6), csv=self.device.csv, finisher=self.finisher,
        )
        if self.publisher is not None:
            ref = meta["profile"]
            self.publisher.announce(meta, info.scale, f"{ref['identity']}@{ref['created']}" if ref else "",
                                    self._profile.data if self._profile is not None else None)

    def _close_writer(self) -> None:
        writer, self.writer = self.writer, None
        if writer is None:
            return
        try:
            writer.close()
        except StorageError as exc:  # a disk that filled up at the very end: what was written is consistent
            self.log(f"{self.device.name}: closing the segment: {exc}")
        self._bytes_closed += writer.bytes_written
        self._segments_closed += writer.segments_finished

    def _stream(self) -> tuple[bool, str | None]:
        """Write what arrives until the connection ends; (samples arrived?, why it ended or None)."""
        session, stall = self.session, self.stall_limit
        streamed = False
        reason: str | None = None
        finished = 0
        try:
            while True:
                self.heartbeat = time.monotonic()
                if self._stop.wait(POLL):
                    break
                n = self._drain()
                now = time.monotonic()
                if n:
                    streamed = True
                    self.last_data = now
                if self.writer.segments_finished != finished:
                    # a segment was finished: the rate measured so far, beside it in the journal
                    finished = self.writer.segments_finished
                    self._journal("clock", segments_finished=finished, clock=session.driver.clock.describe())
                stats = session.stats()
                self.delivered_rate = stats.delivered_rate
                if session.interrupted:
                    # the driver's own stall watch (serial, BLE) uses this device's limit too: the same cause
                    cut = session.interruption
                    reason = (f"stalled: no data for {cut.seconds or stall:g} s while connected ({session.interrupted})"
                              if isinstance(cut, DeviceStalled)
                              else f"disconnected: {session.interrupted}")
                    break
                if session.state == State.ENDED:
                    self._set("ended", "the source delivered everything it had")
                    self.log(f"{self.device.name}: the source ended")
                    break
                if now - self.last_data > stall:
                    reason = f"stalled: no data for {stall:g} s while connected"
                    break
        finally:
            session.stop()
            try:
                self._drain()             # what the pump took before it stopped
            except Exception as exc:
                reason = self._internal_error(exc)
            self._recorder.close()
            clock = session.driver.clock
            self.measured_rate = clock.measured_rate or self.measured_rate
            self._journal("disconnect", reason=reason or (self.stop_reason if self._stop.is_set() else self.state), clock=clock.describe(),
                          last_sample=utc_text(self.last_sample_utc))
            if reason is not None:
                self._pending = PendingGap(reason, self.last_sample_utc)
            self._record_drops()
            self._close_writer()
            self.session = None
        return streamed, reason

    def _drain(self) -> int:
        """Write everything the reader holds (through the Recorder into ``write`` and ``gap``);
        returns the samples taken."""
        chunk = self._recorder.poll()
        if chunk.n:
            self.counts.delivered += chunk.n
            self.last_sample_utc = float(chunk.t[-1])
        return chunk.n

    # the Recorder's writer: write() and gap(), times in UTC ns
    def write(self, t_ns: np.ndarray, counts: np.ndarray, channels: dict | None) -> None:
        """One run of samples: to the segments (calibrated channels added), or counted as dropped."""
        from accelrig.segments import ns_to_seconds

        t = ns_to_seconds(t_ns)
        n = counts.shape[0]
        if self._pending is not None:
            p = self._pending
            self._pending = None
            seconds = float(t[0]) - p.since_utc if p.since_utc is not None else None
            self._write_gap(int(t_ns[0]), p.samples, p.cause, seconds)
        if self._gap_unwritten is not None:
            self._retry_gap_record()
        full = self._disk_full
        if full is not None and time.monotonic() < full["next_try"]:
            self._drop(t, n)    # not yet time to try again
            return
        if self.publisher is not None:
            self.publisher.block(t, counts)
        try:
            self.writer.write(t_ns, counts, self._channels(t, counts, channels))
            self.counts.written += n
        except StorageFull as exc:
            self._drop(t, n, "disk full", str(exc), tried=True)
            return
        except StorageError as exc:   # an I/O error: the same care, its own cause
            self._drop(t, n, "write failed", str(exc), tried=True)
            return
        if full is not None:
            self._writing_again(full, float(t[0]))

    def _writing_again(self, full: dict, resumed: float) -> None:
        """The one gap record of a full disk, once samples are written again.

        Only after a data block went in: a gap record is small enough to fit where a block does
        not, and writing it first declared every retry a recovery (one record and one log line
        per retry while the disk stayed full).  It is placed by its time, before the first
        sample written again."""
        seconds = resumed - full["since"]
        self._disk_full = None
        self._set(*self._streaming_state())
        self._journal("gap", cause=full["cause"], samples=full["samples"], at=utc_text(full["since"]),
                      seconds=seconds)
        self.log(f"{self.device.name}: writing again after {full['cause']} "
                 f"({full['samples']} samples dropped over {seconds:.1f} s)")
        self._gap_unwritten = {"since": full["since"], "samples": full["samples"], "cause": full["cause"],
                               "seconds": seconds}
        self._retry_gap_record()

    def _retry_gap_record(self) -> bool:
        """Write the disk-full gap record the segment refused (placed by its own time, so a later
        write still puts it where the samples went missing); True once it is in."""
        g = self._gap_unwritten
        try:
            self.writer.gap(g["since"], g["samples"], g["cause"], g["seconds"])
        except StorageError as exc:   # the journal has it; tried again before the next block
            self.log(f"{self.device.name}: gap record not written yet ({exc}); the journal has it")
            return False
        self.counts.gaps += 1
        self._gap_unwritten = None
        return True

    def gap(self, t_ns: int, samples: int, cause: str, seconds: float | None = None) -> None:
        """A gap the driver reported (or a reader overrun, which a lossless reader never has)."""
        if samples > 0 and cause != "reader overrun":
            self.counts.missing += samples
        self._write_gap(int(t_ns), samples, cause, seconds)

    def _drop(self, t: np.ndarray, n: int, cause: str = "", error: str | None = None, tried: bool = False) -> None:
        """Samples delivered that cannot be written: counted, and one gap record once writing resumes."""
        self.counts.dropped += n
        if self._disk_full is None:
            self._disk_full = {"since": float(t[0]), "samples": 0, "cause": cause}
            self._set(cause, error)
            self.log(f"{self.device.name}: {cause} ({error}); samples are counted and dropped until writing "
                     "succeeds again")
        self._disk_full["samples"] += n
        if tried:
            self._disk_full["next_try"] = time.monotonic() + DISK_RETRY

    def _channels(self, t: np.ndarray, counts: np.ndarray, channels: dict | None) -> dict[str, np.ndarray] | None:
        from accelrig.acquisition.ringbuffer import Chunk
        from accelrig.profiles.apply import calibrated

        out = dict(channels or {})
        if self._calibrating:
            device = {"hardware_bias_removed": self.info.hardware_bias_removed}
            cal = calibrated(Chunk(0, counts, t, self.info.scale), self._profile, self.device.uncertainty,
                             device=device)
            out.update({name: cal.acc[:, i] for i, name in enumerate(CALIBRATED_CHANNELS)})
            if self.device.uncertainty:
                out.update({name: cal.uncertainty[:, i] for i, name in enumerate(UNCERTAINTY_CHANNELS)})
        return out or None

    def _write_gap(self, at_ns: int, samples: int, cause: str, seconds: float | None) -> None:
        """A gap record before the sample at ``at_ns`` (UTC ns: exactly that sample's time, which places it)."""
        at = at_ns / 1e9
        self._journal("gap", cause=cause, samples=samples, at=utc_text(at), seconds=seconds)
        if self.publisher is not None:
            self.publisher.gap(at, samples, cause, seconds)
        try:
            self.writer.gap(at_ns, samples, cause, seconds)
            self.counts.gaps += 1
        except StorageError as exc:
            # the record could not be written; the journal has it, the disk-full gap will follow
            self.log(f"{self.device.name}: gap record not written ({exc})")

    # ------------------------------------------------------------------ ending
    def _record_drops(self) -> None:
        """Before a writer closes: the gap record of samples dropped and not yet recorded."""
        if self._gap_unwritten is not None and self.writer is not None and not self._retry_gap_record():
            g, self._gap_unwritten = self._gap_unwritten, None   # its journal line was written when it ended
            self.log(f"{self.device.name}: the {g['cause']} gap record ({g['samples']} samples) could not be "
                     "written to the segment; the journal has it")
        full = self._disk_full
        if full is None or self.writer is None:
            return
        try:
            self.writer.gap(full["since"], full["samples"], full["cause"], None)
        except StorageError:
            self.log(f"{self.device.name}: the {full['cause']} gap record ({full['samples']} samples) could not be "
                     "written to the segment; the journal has it")
            self._journal("gap", cause=full["cause"], samples=full["samples"], at=utc_text(full["since"]),
                          seconds=None, in_segment=False)
        else:
            self.counts.gaps += 1
            self._journal("gap", cause=full["cause"], samples=full["samples"], at=utc_text(full["since"]),
                          seconds=None)
        self._disk_full = None

    def _finish(self) -> None:
        self._record_drops()
        self._close_writer()
        if self.publisher is not None:
            self.publisher.close()
        if self.state not in ("failed", "ended"):
            self._set("stopped", self.last_error)
        status = self.status()
        self._journal("stop", counts={**self.counts.__dict__, "bytes_written": status["bytes_written"],
                                      "segments": status["segments"]}, state=self.state,
                      reason=self.stop_reason, last_sample=utc_text(self.last_sample_utc),
                      last_sample_utc=self.last_sample_utc)
        self.log(f"{self.device.name}: stopped: delivered {self.counts.delivered}, written {self.counts.written}, "
                 f"dropped {self.counts.dropped}, missing {self.counts.missing}, gaps {self.counts.gaps}")

    def _journal(self, event: str, **fields) -> None:
        line = json.dumps({"event": event, "utc": utc_text(time.time()), **fields}, default=str)
        try:
            with open(self.directory / "journal.jsonl", "a", encoding="utf-8") as fh:
                fh.write(line + "\n")
        except OSError as exc:
            self.log(f"{self.device.name}: journal not written ({exc.strerror}): {line}")

    # ------------------------------------------------------------------ status
    def status(self) -> dict:
        with self._lock:
            state, error = self.state, self.last_error
        writer = self.writer
        c = self.counts
        bytes_written = self._bytes_closed + (writer.bytes_written if writer is not None else 0)
        segments = self._segments_closed + (writer.segments_finished if writer is not None else 0)
        info = self.info
        return {
            "name": self.device.name,
            "url": self.device.url,
            "state": state,
            "error": error,
            "identity": info.identity if info else None,
            "nominal_rate": info.nominal_rate if info else None,
            "delivered_rate": self.delivered_rate,
            "measured_rate": self._clock_rate(),
            "delivered": c.delivered,
            "written": c.written,
            "dropped": c.dropped,
            "missing": c.missing,
            "gaps": c.gaps,
            "connects": c.connects,
            "failed_connects": c.failed_connects,
            "bytes_written": bytes_written,
            "segments": segments,
            "profile": self.profile_note,
            "output": self.device.output,
            "last_sample": utc_text(self.last_sample_utc),
            "seconds_since_data": round(time.monotonic() - self.last_data, 3) if state == "streaming" else None,
            **({"mqtt": self.publisher.stats()} if self.publisher is not None else {}),
        }

    def _clock_rate(self) -> float | None:
        session = self.session
        if session is not None and isinstance(session.driver, UtcDriver) and session.driver.clock is not None:
            rate = session.driver.clock.measured_rate
            if rate is not None:
                return rate
        return self.measured_rate
