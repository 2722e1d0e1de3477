"""Atomic writes: the file written has the permissions an ordinary new file would have."""

from __future__ import annotations

import os
import stat

import pytest

from stereo_gui.files.atomic import write_text_atomic

posix_only = pytest.mark.skipif(os.name != "posix", reason="POSIX file modes")


@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


@posix_only
def test_new_file_is_readable_by_others_as_the_umask_allows(tmp_path, umask_022):
    """A calibration written in a shared folder must be readable by the other technicians:
    mode 0644 under umask 022, not the 0600 of a temporary file."""
    target = write_text_atomic(tmp_path / "rig.yaml", "x")
    assert stat.S_IMODE(target.stat().st_mode) == 0o644


@posix_only
def test_replacing_a_file_keeps_its_mode(tmp_path, umask_022):
    target = tmp_path / "rig.yaml"
    target.write_text("old")
    target.chmod(0o640)
    write_text_atomic(target, "new")
    assert target.read_text() == "new"
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert [p.name for p in tmp_path.iterdir()] == ["rig.yaml"]  # no temporary file left


# ---- faults at every step of a write ---------------------------------------------------------
from disk_faults import STEPS, install  # noqa: E402

from stereo_gui.core.errors import InputError  # noqa: E402
from stereo_gui.files import atomic  # noqa: E402


@pytest.mark.parametrize("step", STEPS)
def test_a_fault_at_any_step_keeps_the_old_file(tmp_path, monkeypatch, step):
    target = tmp_path / "calib.yaml"
    target.write_bytes(b"the good old calibration")
    disk = install(monkeypatch, step)
    with pytest.raises(InputError, match=f"cannot write {target}") as info:
        atomic.write_bytes_atomic(target, b"new data " * 1000)
    assert disk.failed
    assert "left as it was" in str(info.value) or step == "open"
    assert target.read_bytes() == b"the good old calibration"
    assert [p.name for p in tmp_path.iterdir()] == ["calib.yaml"]


@pytest.mark.parametrize("step", ["open", "fsync", "replace"])
def test_a_fault_after_a_library_wrote_the_path_keeps_the_old_file(tmp_path, monkeypatch, step):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    # atomic_path opens the temporary file (1), reopens it for fsync; the fault hits the first
    disk = install(monkeypatch, step)
    with pytest.raises(InputError):
        with atomic.atomic_path(target) as tmp:
            tmp.write_bytes(b"written by a library")
    assert disk.failed
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]


def test_a_library_that_wrote_nothing_or_garbage_is_refused(tmp_path):
    target = tmp_path / "calib.yaml"
    target.write_bytes(b"old")
    with pytest.raises(InputError, match="nothing reached the disk"):
        with atomic.atomic_path(target):
            pass  # cv2.FileStorage on a full disk: an empty file and no error

    def verify(path):
        raise ValueError("line 3: truncated")

    with pytest.raises(InputError, match="does not read back .*line 3: truncated"):
        with atomic.atomic_path(target, verify=verify) as tmp:
            tmp.write_bytes(b"torn")
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["calib.yaml"]


def test_several_files_are_replaced_only_when_all_were_written(tmp_path, monkeypatch):
    a, b = tmp_path / "left.yaml", tmp_path / "right.yaml"
    a.write_bytes(b"old left")
    b.write_bytes(b"old right")
    install(monkeypatch, "write", nth=2)  # the second file hits the full disk
    with pytest.raises(InputError, match="right.yaml"):
        atomic.write_many_atomic([(a, b"new left", None), (b, b"new right", None)])
    assert a.read_bytes() == b"old left" and b.read_bytes() == b"old right"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["left.yaml", "right.yaml"]


@pytest.mark.parametrize("failing", [1, 3, 4])
def test_a_rename_that_fails_in_a_set_puts_back_those_already_replaced(tmp_path, monkeypatch,
                                                                       failing):
    """All or nothing to the end: the k-th rename of four fails, the earlier files replaced
    get their old contents back, a file that did not exist before is gone again."""
    names = ["a.png", "b.npy", "c.png", "new.ply"]
    for name in names[:3]:
        (tmp_path / name).write_bytes(b"old " + name.encode())
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    disk = install(monkeypatch, "replace", rename=failing)
    with pytest.raises(InputError, match=rf"cannot write .*{names[failing - 1]}: No space.*"
                                         r"the outputs was not written: every file it would "
                                         r"have replaced is as it was"):
        atomic.write_many_atomic([(tmp_path / n, b"new " + n.encode(), None) for n in names],
                                 what="the outputs")
    assert disk.failed
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before  # nothing left over


def test_a_set_written_whole_leaves_no_earlier_copies(tmp_path):
    for name in ("a", "b"):
        (tmp_path / name).write_bytes(b"old")
    atomic.write_many_atomic((tmp_path / n, b"new", None) for n in ("a", "b", "c"))
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == {
        "a": b"new", "b": b"new", "c": b"new"}


def test_os_errors_are_said_in_words():
    import errno

    assert atomic.os_error_text(OSError(errno.EACCES, "Permission denied")) == "permission denied"
    assert "No space left" in atomic.os_error_text(OSError(errno.ENOSPC, "x"))


def test_a_calibration_save_checks_what_filestorage_wrote(tmp_path, monkeypatch):
    """cv2.FileStorage reports no failed write; a torn file must not replace the good one."""
    from factories import make_calibration

    from stereo_gui.files import calibration_file as cf

    target = tmp_path / "calib.yaml"
    cf.save_calibration(make_calibration(), target)
    before = target.read_bytes()
    real = cf.calibration_text
    monkeypatch.setattr(cf, "calibration_text", lambda c: real(c)[:2500])  # a torn file
    with pytest.raises(InputError, match="does not read back"):
        cf.save_calibration(make_calibration(0.5), target)
    assert target.read_bytes() == before
