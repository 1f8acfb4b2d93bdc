"""The daemon: its devices, signals, status lines, status socket, systemd notifications.

* SIGTERM / SIGINT: every device flushes and closes its segments; exit 0
  (within ``STOP_SECONDS``: a driver read that hangs longer is abandoned).
* SIGHUP: the configuration is read again.  Devices added start, removed ones
  stop cleanly, changed ones (their entry, or a setting they use) restart, and
  so does one recording raw whose missing profile is there now; unchanged ones
  keep streaming untouched, so their data have no gap.  A device whose old
  runner does not stop within ``STOP_SECONDS`` (a driver call hangs) restarts
  once that one has returned and closed its segments, not beside it.  A
  configuration that no longer validates is refused in the log and the old
  one kept: a typo must not stop the recording.
* Every ``status_interval`` seconds one status line per device on standard
  error (journald keeps it under systemd).
* systemd ``Type=notify``: READY=1 once every device has been opened (or
  failed its first try: one missing device must not hold the others back),
  WATCHDOG=1 only while every device's loop is turning, STATUS= a summary.
"""

from __future__ import annotations

import gc
import os
import signal
import sys
import threading
import time
from pathlib import Path

from accelrig.daemon.config import DaemonConfig, check_mqtt, check_output_writable, check_urls, load_config
from accelrig.daemon.device import DeviceRunner
from accelrig.daemon.notify import notify, watchdog_interval
from accelrig.daemon.status import StatusServer, mqtt_summary
from accelrig.errors import AccelrigError

STOP_SECONDS = 4.0   # every device joined within this; the daemon must be gone within 5 s of SIGTERM
TICK = 0.2


def log(line: str) -> None:
    stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    sys.stderr.write(f"{stamp} accelrig daemon: {line}\n")
    sys.stderr.flush()


def _device_settings(config: DaemonConfig) -> tuple:
    """The daemon-wide settings a device runner uses: a change restarts every device."""
    return (config.output, config.segment_seconds, config.segment_megabytes, config.stall_seconds,
            config.reconnect_initial, config.reconnect_max, config.profile_store, config.mqtt)


class Daemon:
    def __init__(self, config_path: str | os.PathLike):
        self.config_path = Path(config_path)
        self.config = load_config(self.config_path)
        check_urls(self.config)
        check_output_writable(self.config.output)
        if self.config.mqtt is not None:
            check_mqtt(self.config.mqtt)
        self.runners: dict[str, DeviceRunner] = {}
        self._stopping: dict[str, DeviceRunner] = {}   # removed or restarted by a reload, not yet returned
        self.started = time.time()
        self.reloads = 0
        self._stop = threading.Event()
        self._reload = threading.Event()
        self._ready_sent = False
        self.server: StatusServer | None = None
        self.metrics = None
        self.finisher = None

    # ------------------------------------------------------------------ running
    def run(self) -> int:
        # One thread finishes every device's rotated segments, one at a time; creating it loads
        # pyarrow now, not at the first rotation or at SIGTERM (the import's second or two stays
        # out of the 5 s a stop may take, and its memory is in the baseline, not a later jump).
        from accelrig.segments import Finisher

        self.finisher = Finisher(log)
        for signum in (signal.SIGTERM, signal.SIGINT):
            signal.signal(signum, lambda *_: self._stop.set())
        signal.signal(signal.SIGHUP, lambda *_: self._reload.set())
        # every configured device is listed from the status socket's first answer ("starting" until its
        # thread connects): a device that takes long to start (a crashed run's segment to recover) must
        # not hide the ones after it
        for device in self.config.devices:
            self._add(device)
        self.server = StatusServer(self.config.status_socket, self.snapshot)
        self.server.start()
        try:
            self._start_metrics()
            log(f"started (pid {os.getpid()}), config {self.config_path}, output {self.config.output}, "
                f"{len(self.config.devices)} device(s), status socket {self.config.status_socket}")
            # What is loaded by now (numpy, scipy, pyarrow, the drivers: some 100 000 objects) stays
            # for the daemon's life: out of the cyclic collector's sight, a full collection takes
            # 0.1 ms instead of about 100 ms, during which no device is read (an I2C FIFO holds 21 ms).
            gc.freeze()
            for runner in list(self.runners.values()):
                runner.start()
            self._loop()
        finally:
            self._shutdown()
        return 0

    def _loop(self) -> None:
        watchdog = watchdog_interval()
        next_watchdog = time.monotonic()
        next_status = time.monotonic() + self.config.status_interval
        while not self._stop.wait(TICK):
            if self._reload.is_set():
                self._reload.clear()
                self.reload()
            now = time.monotonic()
            if not self._ready_sent and all(r.counts.connects or r.counts.failed_connects or r.state == "failed"
                                            for r in self.runners.values()):
                self._ready_sent = True
                notify(f"READY=1\nSTATUS={self.summary()}")
                log(f"ready: {self.summary()}")
            if watchdog is not None and self._ready_sent and now >= next_watchdog:
                sick = [r.device.name for r in self.runners.values() if not r.healthy]
                if not sick:   # a hung device loop stops the pings, and systemd restarts us
                    notify(f"WATCHDOG=1\nSTATUS={self.summary()}")
                else:
                    notify(f"STATUS=not healthy: {', '.join(sick)} not turning")
                next_watchdog = now + watchdog
            if self.config.status_interval and now >= next_status:
                self.status_lines()
                notify(f"STATUS={self.summary()}")
                next_status = now + self.config.status_interval

    def _shutdown(self) -> None:
        notify("STOPPING=1")
        log("stopping: flushing and closing every device's segments")
        for runner in self.runners.values():
            runner.stop()
        deadline = time.monotonic() + STOP_SECONDS
        for runner in [*self._stopping.values(), *self.runners.values()]:
            if not runner.join(max(deadline - time.monotonic(), 0.0)):
                log(f"{runner.device.name}: did not stop within {STOP_SECONDS:g} s (a driver call hangs); "
                    "its open segment will be recovered at the next start")
        if self.finisher is not None:
            self.finisher.close(0.5)   # the runners have finished what they had pending
        if self.server is not None:
            self.server.stop()
        if self.metrics is not None:
            self.metrics.shutdown()
        log("stopped")

    def _add(self, device) -> DeviceRunner:
        """A device's runner, listed in status (state "starting") before it is started."""
        runner = DeviceRunner(device, self.config, log, finisher=self.finisher)
        self.runners[device.name] = runner
        return runner

    # ------------------------------------------------------------------ reload
    def reload(self) -> None:
        try:
            new = load_config(self.config_path)
            check_urls(new)
            check_output_writable(new.output)
            if new.mqtt is not None:
                check_mqtt(new.mqtt)
        except AccelrigError as exc:
            log(f"reload refused, the running configuration is kept: {exc}")
            return
        old = self.config
        everything = _device_settings(old) != _device_settings(new)
        old_devices = {d.name: d for d in old.devices}
        new_devices = {d.name: d for d in new.devices}
        stop = [name for name, d in old_devices.items()
                if name not in new_devices or everything or not d.same_as(new_devices[name])]
        # a device recording raw for want of its profile is restarted once the profile is there (filed in
        # the store, or the file fixed): the reload an operator sends after calibrating it
        found = [name for name in new_devices if name not in stop and name in self.runners
                 and self.runners[name].profile_now_usable()]
        for name in stop:
            self.runners[name].stop("removed from the configuration" if name not in new_devices
                                    else "restarted: its configuration changed")
        for name in found:
            self.runners[name].stop("restarted: the profile it lacked is there now")
        stop += found
        deadline = time.monotonic() + STOP_SECONDS
        for name in stop:
            runner = self.runners.pop(name)
            if not runner.join(max(deadline - time.monotonic(), 0.0)):
                self._stopping[name] = runner
                log(f"{name}: did not stop within {STOP_SECONDS:g} s (a driver call hangs); it stops when it returns"
                    + (", and its new run starts then (it waits, its segments are not written beside the old "
                       "ones)" if name in new_devices else ""))
        self._stopping = {name: r for name, r in self._stopping.items() if not r.join(0)}
        self.config = new
        if new.status_socket != old.status_socket:
            self.server.stop()
            self.server = StatusServer(new.status_socket, self.snapshot)
            self.server.start()
        started = []
        for device in new.devices:
            if device.name not in self.runners:
                self._add(device)
                started.append(device.name)
            else:
                self.runners[device.name].device = device  # same entry; its place in the list may differ
        self.runners = {d.name: self.runners[d.name] for d in new.devices}   # listed in the file's order
        for name in started:
            self.runners[name].start(after=self._stopping.get(name))
        self.reloads += 1
        removed = [n for n in stop if n not in new_devices]
        restarted = [n for n in stop if n in new_devices and n not in found]
        added = [n for n in started if n not in restarted and n not in found]
        kept = [n for n in new_devices if n not in started]
        def names(group: list[str]) -> str:
            return ", ".join(group) or "none"

        log(f"reloaded {self.config_path}: added {names(added)}; removed {names(removed)}; "
            f"restarted {names(restarted)}; unchanged {names(kept)}"
            + (f"; restarted with the profile they lacked: {names(found)}" if found else ""))
        for name in new_devices:
            runner = self.runners[name]
            if name not in started and runner.profile_problem is not None:
                log(f"{name}: still {runner.profile_problem}")

    # ------------------------------------------------------------------ health
    def snapshot(self) -> dict:
        return {
            "daemon": {
                "pid": os.getpid(),
                "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(self.started)),
                "uptime": time.time() - self.started,
                "config": str(self.config_path),
                "output": str(self.config.output),
                "reloads": self.reloads,
                "ready": self._ready_sent,
            },
            "devices": [runner.status() for runner in list(self.runners.values())],
        }

    def summary(self) -> str:
        states: dict[str, int] = {}
        for runner in self.runners.values():
            states[runner.state] = states.get(runner.state, 0) + 1
        return ", ".join(f"{n} {state}" for state, n in sorted(states.items())) or "no devices"

    def status_lines(self) -> None:
        for runner in list(self.runners.values()):
            d = runner.status()
            rate = f"{d['delivered_rate']:.1f} Hz" if d["delivered_rate"] else "- Hz"
            line = (f"{d['name']}: {d['state']}, {rate}, delivered {d['delivered']}, written {d['written']}, "
                    f"dropped {d['dropped']}, missing {d['missing']}, gaps {d['gaps']}, "
                    f"{d['bytes_written'] / 1e6:.1f} MB, profile {d['profile']}")
            if d["error"]:
                line += f" ({d['error']})"
            if d.get("mqtt"):
                line += f"; mqtt: {mqtt_summary(d['mqtt'])}"
            log(line)

    def _start_metrics(self) -> None:
        if self.config.metrics_port is None:
            return
        from accelrig.daemon.metrics import serve_metrics

        self.metrics = serve_metrics(self.config.metrics_port, self.snapshot)


def run_daemon(config_path: str | os.PathLike) -> int:
    """``accelrig daemon --config FILE``: refuse a bad configuration in one line, else run until stopped."""
    return Daemon(config_path).run()
