"""The headless acquisition daemon (``accelrig daemon``): several devices streamed to disk for weeks.

    config.py      the daemon.yaml description (validator and published JSON Schema), loading, checks
    clock.py       absolute UTC time per sample: host clock anchored, device clock rate measured
    device.py      one device supervised: connect, flash, stream to segments, reconnect, gaps
    service.py     the daemon: devices, signals (TERM/INT stop, HUP reload), status lines, watchdog
    status.py      the owner-only status socket, its client, and the status table
    notify.py      systemd's notify protocol (READY, WATCHDOG, STATUS) written directly

The core of the daemon imports no textual; the TUI's daemon screen reads the
status socket through ``status.query``.
"""
