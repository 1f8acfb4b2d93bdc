"""Writes that never destroy: special files, inputs, existing files, symlinks, the profile store, OSErrors."""

from __future__ import annotations

import errno
import os
import stat
import threading

import pytest

from accelrig.errors import DataError
from accelrig.files import atomic_write
from accelrig.profiles import load_profile, save_profile
from accelrig.profiles.store import ProfileStore
from hostile.support import EXAMPLE_PROFILE, assert_refused, snapshot

RECORD = ("record", "sim://still?pace=fast&seed=2", "--samples", "300")


@pytest.fixture
def raw(tmp_path, cli):
    """A raw recording of the example profile's device."""
    path = tmp_path / "raw.csv"
    assert cli("record", "sim://still?pace=fast&seed=11", "--samples", "300", "-o", path).returncode == 0
    return path


def _special(tmp_path, kind):
    path = tmp_path / kind
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "device":
        try:
            os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))   # a second /dev/null, inside the test folder
        except PermissionError:
            pytest.skip("no permission to make a device node here")
    elif kind == "folder":
        path.mkdir()
    return path


SPECIAL = [("fifo", "is a fifo"), ("device", "is a device"), ("folder", "is a directory")]


# record -o FOLDER records segments into the folder, so a folder is not a special target for record
@pytest.mark.parametrize("command, kind, cause", [(command, kind, cause) for command in ("record", "apply", "calibrate")
                                                  for kind, cause in SPECIAL if (command, kind) != ("record", "folder")])
def test_output_onto_a_special_file_is_refused(command, kind, cause, guarded, tmp_path, raw):
    if command == "record":
        cause = "exists and is not a folder"   # no suffix: record takes it for a segment folder
    target = _special(tmp_path, kind)
    argv = {"record": (*RECORD, "-o", target, "--force"),
            "apply": ("profile", "apply", EXAMPLE_PROFILE, raw, "-o", target, "--force"),
            "calibrate": ("calibrate", "static", raw, "-o", target, "--force")}[command]
    before = snapshot(tmp_path)
    assert_refused(guarded(*argv), f"{target}: {cause}")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", ["record", "apply", "calibrate static", "calibrate wheel"])
def test_existing_output_needs_force(command, guarded, tmp_path, raw):
    out = tmp_path / ("out.yaml" if command.startswith("calibrate") else "out.csv")
    out.write_text("precious\n")
    argv = {"record": (*RECORD, "-o", out),
            "apply": ("profile", "apply", EXAMPLE_PROFILE, raw, "-o", out),
            "calibrate static": ("calibrate", "static", raw, "-o", out),
            "calibrate wheel": ("calibrate", "wheel", raw, "--radius", "0.28", "-o", out)}[command]
    before = snapshot(tmp_path)
    assert_refused(guarded(*argv), f"{out}: exists.*--force")
    assert snapshot(tmp_path) == before


def test_record_force_replaces_and_a_symlink_is_written_through(cli, tmp_path):
    target = tmp_path / "shared.csv"
    target.write_text("old\n")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    assert cli(*RECORD, "-o", link, "--force").returncode == 0
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text().startswith("# accelrig-meta")


def test_apply_never_writes_over_its_own_input(guarded, tmp_path, raw):
    before = snapshot(tmp_path)
    assert_refused(guarded("profile", "apply", EXAMPLE_PROFILE, raw, "-o", raw, "--force"), "also an input")
    link = tmp_path / "alias.csv"
    link.symlink_to(raw)
    before = snapshot(tmp_path)
    assert_refused(guarded("profile", "apply", EXAMPLE_PROFILE, raw, "-o", link, "--force"), "also an input")
    assert snapshot(tmp_path) == before


def test_noise_into_a_symlinked_profile_updates_the_target_and_keeps_the_link(cli, tmp_path):
    still = tmp_path / "still.csv"
    assert cli("record", "sim://still?pace=fast&seed=11", "--seconds", "60", "-o", still).returncode == 0
    shared = tmp_path / "shared"
    shared.mkdir()
    target = shared / "p.yaml"
    profile = load_profile(EXAMPLE_PROFILE)
    profile.data["noise"] = None
    save_profile(profile, target)
    link = tmp_path / "p.yaml"
    link.symlink_to(target)
    assert cli("noise", still, "--profile", link).returncode == 0
    assert link.is_symlink() and load_profile(target).noise is not None
    # a second run would replace the figures: only with --force
    before = snapshot(tmp_path)
    assert_refused(cli("noise", still, "--profile", link), "already holds noise figures")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("failure, cause", [
    (errno.ENOSPC, "No space left on device"), (errno.EROFS, "Read-only file system"),
    (errno.EFBIG, "File too large"), (errno.EACCES, "Permission denied"),
])
def test_every_oserror_on_write_is_one_line_and_leaves_the_old_file(failure, cause, guarded, tmp_path, raw,
                                                                   monkeypatch):
    out = tmp_path / "out.csv"
    out.write_text("precious\n")
    real_fsync = os.fsync

    def failing_fsync(fd):
        if failure in (errno.ENOSPC, errno.EFBIG):
            raise OSError(failure, os.strerror(failure))
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", failing_fsync)
    if failure in (errno.EROFS, errno.EACCES):
        import tempfile

        def failing_mkstemp(*args, **kwargs):
            raise OSError(failure, os.strerror(failure))

        monkeypatch.setattr(tempfile, "mkstemp", failing_mkstemp)
    before = snapshot(tmp_path)
    assert_refused(guarded("profile", "apply", EXAMPLE_PROFILE, raw, "-o", out, "--force"), cause)
    assert snapshot(tmp_path) == before


def test_file_size_limit_is_one_line(limited, tmp_path):
    """ulimit -f: Python ignores SIGXFSZ, the write raises EFBIG, the old file stays."""
    out = tmp_path / "out.csv"
    out.write_text("precious\n")
    script = ("import resource, sys\nresource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))\n"
              "from accelrig.cli import main\nsys.exit(main(sys.argv[1:]))")
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", script, *RECORD, "-o", str(out), "--force"], capture_output=True,
                          text=True, timeout=30, stdin=subprocess.DEVNULL)
    assert_refused(proc, "File too large")
    assert out.read_text() == "precious\n"


def test_atomic_write_refuses_before_creating_anything(tmp_path):
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    with pytest.raises(DataError, match="is a fifo"):
        atomic_write(fifo, lambda fh: fh.write("x"), text=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


# ------------------------------------------------------------------ the profile store


def _add_concurrently(store: ProfileStore, profile, n: int) -> tuple[list, list]:
    barrier = threading.Barrier(n)
    paths, errors = [], []

    def add():
        barrier.wait()
        try:
            paths.append(store.add(profile.copy()))
        except Exception as exc:   # noqa: BLE001 - collected and asserted by the caller
            errors.append(exc)

    threads = [threading.Thread(target=add) for _ in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return paths, errors


def test_concurrent_adds_all_land(tmp_path):
    profile = load_profile(EXAMPLE_PROFILE)
    for round_ in range(3):
        store = ProfileStore(tmp_path / f"store{round_}")
        paths, errors = _add_concurrently(store, profile, 5)
        assert not errors
        assert len(set(paths)) == 5 and len(store.entries()) == 5


def test_store_modes_ignore_a_permissive_umask(cli, tmp_path):
    old = os.umask(0)
    try:
        assert cli("profile", "add", EXAMPLE_PROFILE, "--store", tmp_path / "store").returncode == 0
    finally:
        os.umask(old)
    for path in [tmp_path / "store", *(tmp_path / "store").rglob("*")]:
        mode = stat.S_IMODE(path.stat().st_mode)
        assert mode == (0o755 if path.is_dir() else 0o644), (path, oct(mode))


def test_store_refuses_a_link_out_of_itself(guarded, tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "20260101T000000Z-static.yaml").write_text(EXAMPLE_PROFILE.read_text())
    store = tmp_path / "store"
    store.mkdir()
    (store / "sim-random-11-00000000").symlink_to(outside)
    # not followed: listed as broken and named on stderr (one bad entry stops no other device)
    result = guarded("profile", "list", "--store", store)
    assert result.returncode == 0 and "Traceback" not in result.stderr
    assert "links outside the store" in result.stderr and "refusing to follow it" in result.stderr
    assert "20260101T000000Z" not in result.stdout and result.stdout.splitlines()[-1].startswith("BROKEN")


def test_store_names_an_unreadable_folder(guarded, tmp_path, monkeypatch):
    store = tmp_path / "store"
    assert guarded("profile", "add", EXAMPLE_PROFILE, "--store", store).returncode == 0
    device = next(store.iterdir())
    real_scandir = os.scandir

    def scandir(path="."):
        if os.fspath(path) == str(device):
            raise PermissionError(errno.EACCES, "Permission denied")
        return real_scandir(path)

    monkeypatch.setattr(os, "scandir", scandir)   # root reads any folder: simulate what a user meets
    result = guarded("profile", "list", "--store", store)   # skipped and named; the other devices stay listed
    assert result.returncode == 0 and f"{device}: cannot read the store folder" in result.stderr
    assert_refused(guarded("profile", "show", "sim-random-11", "--store", store),
                   f"{device}: cannot read the store folder")


def test_an_unwritable_store_is_one_line(guarded, tmp_path):
    blocker = tmp_path / "store"
    blocker.write_text("a file where the store should be\n")
    assert_refused(guarded("profile", "add", EXAMPLE_PROFILE, "--store", blocker), "store")
