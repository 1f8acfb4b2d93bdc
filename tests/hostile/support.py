"""Helpers of the hostile-input cases (issue 19): every bad input ends in one line on stderr naming the cause,
a non-zero exit, no traceback, nothing written or overwritten, in bounded time and memory.

``cli`` (tests/conftest.py) runs a case in-process: cheap, and tracemalloc bounds its memory.
``limited`` runs it as a real process under RLIMIT_AS and a timeout: for the cases built to
hang or exhaust memory (alias bombs, zip bombs, endless devices), which must not take the
test run down with them.
"""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
EXAMPLE_PROFILE = REPO / "profiles" / "example-static_faces-vp.yaml"

# Address space of a limited case: the interpreter with numpy and scipy maps ~0.5-0.8 GiB.
MEMORY_LIMIT = 1536 * 1024 * 1024
TIME_LIMIT = 20.0

_LIMITED = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, ({limit}, {limit}))
from accelrig.cli import main
sys.exit(main(sys.argv[1:]))
"""


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` with its size, mtime and inode: 'nothing written' is equality."""
    out = {}
    for path in sorted(Path(folder).rglob("*")):
        st = path.lstat()
        out[str(path)] = (st.st_mode, st.st_size, st.st_mtime_ns, st.st_ino)
    return out


def assert_refused(result, cause: str) -> None:
    """Non-zero exit, exactly one line on stderr, an accelrig error naming ``cause`` (a regex), no traceback."""
    lines = result.stderr.splitlines()
    assert result.returncode not in (0, None), f"exit {result.returncode}: {result.stderr!r}"
    assert "Traceback" not in result.stderr, result.stderr
    assert len(lines) == 1, f"expected one line on stderr, got {result.stderr!r}"
    assert lines[0].startswith("accelrig: error: "), lines[0]
    assert re.search(cause, lines[0]), f"{cause!r} not in {lines[0]!r}"
    assert not any(ord(c) < 32 or ord(c) == 127 for c in lines[0]), f"control characters in {lines[0]!r}"


