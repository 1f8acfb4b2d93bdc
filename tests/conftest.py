import os

import pytest


@pytest.fixture(autouse=True)
def _isolated_user_dirs(tmp_path_factory, monkeypatch):
    """Never touch the real user's data directory from a test."""
    home = tmp_path_factory.mktemp("home")
    monkeypatch.setenv("ACCELRIG_HOME", str(home))
    monkeypatch.setenv("XDG_DATA_HOME", str(home / "xdg"))
    yield
