"""Fault injection for stereo_gui.files.atomic: make one step of the n-th file written fail.

`FaultyDisk(step, nth)` installed on `atomic.syscalls` (monkeypatch) lets files 1..nth-1
through and makes the n-th file's `step` fail as a full disk does:

- "open": the temporary file cannot be created (ENOSPC)
- "write": half the data is written, then ENOSPC
- "short": every write writes at most half of what it is given, the last ones nothing (a
  device that silently stops taking data; atomic must not loop forever nor accept it)
- "fsync": the data does not reach the disk (EIO)
- "close": close reports the lost write (ENOSPC, as NFS does)
- "replace": the rename fails (ENOSPC); with `rename=k`, the k-th rename made (a set of files
  is renamed only once all of it is written, so its k-th file's rename)
"""

from __future__ import annotations

import errno
import os

STEPS = ("open", "write", "short", "fsync", "close", "replace")


class FaultyDisk:
    def __init__(self, step: str, nth: int = 1, rename: int | None = None) -> None:
        assert step in STEPS, step
        self.step = step
        self.nth = nth
        self.rename = rename
        self.renames = 0
        self.files = 0
        self.failed = False
        self._fd: int | None = None  # the descriptor of the n-th file
        self._short_budget = 0

    def _hit(self) -> bool:
        return self.files == self.nth

    def open(self, path, flags, mode=0o777):
        is_temp = bool(flags & os.O_CREAT)
        if is_temp:
            self.files += 1
            if self._hit() and self.step == "open":
                self.failed = True
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        fd = os.open(path, flags, mode)
        if is_temp and self._hit():
            self._path = str(path)
            self._fd = fd
            self._short_budget = 3
        elif not is_temp and str(path) == getattr(self, "_path", None):
            self._fd = fd  # the same file opened again (to fsync what a library wrote)
        return fd

    def write(self, fd, data):
        if fd == self._fd and self.step == "write":
            os.write(fd, bytes(data[: len(data) // 2]))
            self.failed = True
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        if fd == self._fd and self.step == "short":
            self.failed = True
            if self._short_budget <= 0:
                return 0
            self._short_budget -= 1
            return os.write(fd, bytes(data[: max(1, len(data) // 2)]))
        return os.write(fd, data)

    def fsync(self, fd):
        if fd == self._fd and self.step == "fsync":
            self.failed = True
            raise OSError(errno.EIO, os.strerror(errno.EIO))
        return os.fsync(fd)

    def close(self, fd):
        os.close(fd)
        if fd == self._fd:
            self._fd = None if self.step != "replace" else -2
            if self.step == "close":
                self.failed = True
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    def replace(self, src, dst):
        self.renames += 1
        if self.step == "replace" and self.rename is not None:
            if self.renames == self.rename and not self.failed:
                self.failed = True
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return os.replace(src, dst)
        if self.step == "replace" and self._hit() and not self.failed:
            self.failed = True
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return os.replace(src, dst)


def install(monkeypatch, step: str, nth: int = 1, rename: int | None = None) -> FaultyDisk:
    """Make the n-th file written through stereo_gui.files.atomic fail at `step` (or, with
    step "replace" and `rename`, the rename-th rename)."""
    from stereo_gui.files import atomic

    disk = FaultyDisk(step, nth, rename)
    for name in ("open", "write", "fsync", "close", "replace"):
        monkeypatch.setattr(atomic.syscalls, name, getattr(disk, name))
    return disk
