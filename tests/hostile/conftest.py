"""Fixtures of the hostile-input cases (issue 19); the helpers and what they check are in support.py."""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import sys
import time
from types import SimpleNamespace

import pytest

from hostile.support import _LIMITED, EXAMPLE_PROFILE, MEMORY_LIMIT, TIME_LIMIT


@pytest.fixture
def limited(tmp_path):
    """A case as a real process under RLIMIT_AS and a timeout; returns returncode, stdout, stderr, seconds."""

    def call(*args, cwd=None, timeout: float = TIME_LIMIT, memory: int = MEMORY_LIMIT):
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
        start = time.monotonic()
        try:
            proc = subprocess.run([sys.executable, "-c", _LIMITED.format(limit=memory), *map(str, args)],
                                  capture_output=True, text=True, timeout=timeout, cwd=cwd or tmp_path, env=env,
                                  stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            pytest.fail(f"accelrig {' '.join(map(str, args))} did not finish in {timeout} s")
        return SimpleNamespace(returncode=proc.returncode, stdout=proc.stdout, stderr=proc.stderr,
                               seconds=time.monotonic() - start)

    return call


@pytest.fixture
def guarded(cli):
    """A case in-process under a memory and a time limit: RLIMIT_AS raised to what the process maps now
    plus ``memory_mb``, and an interval timer; both restored after.  A case that would exhaust memory
    or hang fails the test instead of the machine."""

    def call(*args, memory_mb: float = 400.0, seconds: float = 10.0):
        page = os.sysconf("SC_PAGE_SIZE")
        with open("/proc/self/statm") as fh:
            mapped = int(fh.read().split()[0]) * page
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)

        def too_slow(signum, frame):
            raise TimeoutError(f"accelrig {' '.join(map(str, args))} did not finish in {seconds} s")

        previous = signal.signal(signal.SIGALRM, too_slow)
        resource.setrlimit(resource.RLIMIT_AS, (mapped + int(memory_mb * 2**20), hard))
        signal.setitimer(signal.ITIMER_REAL, seconds)
        try:
            return cli(*args)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
            signal.signal(signal.SIGALRM, previous)

    return call


@pytest.fixture
def profile_text() -> str:
    return EXAMPLE_PROFILE.read_text()
