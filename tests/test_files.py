"""atomic_write: whole files only, readable by others as the umask says, no leftovers."""

import os
import stat

import pytest

from accelrig.errors import DataError
from accelrig.files import atomic_write, read_text_file


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o002, 0o664), (0o077, 0o600)])
def test_written_file_gets_the_umask_mode_not_a_private_one(tmp_path, umask, mode):
    old = os.umask(umask)
    try:
        atomic_write(tmp_path / "p.yaml", lambda fh: fh.write("x: 1\n"), text=True)
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "p.yaml").stat().st_mode) == mode
    assert (tmp_path / "p.yaml").read_text() == "x: 1\n"


def test_a_failing_writer_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "keep.csv"
    target.write_text("old\n")

    def broken(fh):
        fh.write("half")
        raise RuntimeError("disk on fire")

    with pytest.raises(RuntimeError):
        atomic_write(target, broken, text=True)
    assert target.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.csv"]


def test_missing_directory_and_unreadable_files_are_one_line_errors(tmp_path):
    with pytest.raises(DataError, match="does not exist"):
        atomic_write(tmp_path / "no" / "x.csv", lambda fh: None, text=True)
    with pytest.raises(DataError, match="no such file"):
        read_text_file(tmp_path / "missing.csv")
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(DataError, match="not a text file"):
        read_text_file(tmp_path / "bin.csv")
    with pytest.raises(DataError, match="is a directory"):
        read_text_file(tmp_path)
