"""A progress line on stderr for command-line work that takes more than about 2 s.

Shown only on a terminal and never under CI (``CI`` set): pipes, logs and
``--json`` consumers see nothing.  It says what runs, the seconds so far and,
when the work reports it, how far it is ("test 3 of 12"); the line is erased
when the work ends, so the result printed next stands alone.
"""

from __future__ import annotations

import os
import sys
import threading
import time

SHOW_AFTER = 2.0   # s: quicker work prints nothing extra
INTERVAL = 0.5     # s between redraws


def wanted(stream) -> bool:
    return bool(getattr(stream, "isatty", lambda: False)()) and not os.environ.get("CI")


class Progress:
    """``with Progress("fitting the wheel"):`` ... ``progress.step("test 3 of 12")``."""

    def __init__(self, what: str, stream=None, show_after: float = SHOW_AFTER):
        self.what = what
        self.stream = stream if stream is not None else sys.stderr
        self.show_after = show_after
        self.detail = ""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._shown = 0   # characters on the line now

    def step(self, detail: str) -> None:
        self.detail = detail

    def __enter__(self) -> Progress:
        if wanted(self.stream):
            self._start = time.monotonic()
            self._thread = threading.Thread(target=self._run, name="accelrig-progress", daemon=True)
            self._thread.start()
        return self

    def _run(self) -> None:
        if self._stop.wait(self.show_after):
            return
        while not self._stop.is_set():
            line = f"{self.what} ... {time.monotonic() - self._start:.0f} s" + (f"  {self.detail}" if self.detail else "")
            self.stream.write("\r" + line.ljust(self._shown))
            self.stream.flush()
            self._shown = len(line)
            self._stop.wait(INTERVAL)

    def __exit__(self, *exc) -> None:
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join()
        if self._shown:
            self.stream.write("\r" + " " * self._shown + "\r")
            self.stream.flush()
