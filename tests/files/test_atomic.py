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
