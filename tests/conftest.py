import os

# One BLAS thread: the fits here are small, and threaded BLAS on a 2-core machine
# running other work is many times slower, not faster (must be set before numpy loads).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from types import SimpleNamespace

import pytest

from accelrig.cli import main
from mqtt_support import broker  # noqa: F401  (a real Mosquitto, for the fleet tests)


@pytest.fixture(autouse=True)
def _isolated_user_dirs(tmp_path_factory, monkeypatch):
    """Never touch the real user's data directory from a test."""
    home = tmp_path_factory.mktemp("home")
    monkeypatch.setenv("ACCELRIG_HOME", str(home))
    monkeypatch.setenv("XDG_DATA_HOME", str(home / "xdg"))
    yield


@pytest.fixture
def cli(capsys):
    """The CLI in-process (each real process costs seconds of import on a loaded machine)."""

    def call(*args):
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return SimpleNamespace(returncode=code, stdout=captured.out, stderr=captured.err)

    return call

