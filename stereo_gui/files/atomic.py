"""Atomic writes of user data: write a temporary file next to the target, check it, rename it.

Every writer of the application goes through here. The data is written to a new temporary file
in the target's folder (open, write, fsync, close), the temporary file is checked (its size
against the bytes written, and, when the caller gives one, a `verify` function that reads it back
as the format it is: a calibration is re-parsed, a workbook's zip is tested, ...), and only then
renamed over the target. A full disk, an I/O error at any step or a file that does not read back
raises InputError naming the target, the temporary file is removed and the earlier target stays
byte for byte as it was.

Writers that must hand a path to a library (cv2.VideoWriter, ...) use `atomic_path`, which does
the same checks after the library is done. Libraries that can write to memory (cv2.FileStorage,
openpyxl, numpy) should: the bytes then go through `write_bytes_atomic`, where every error of the
disk is seen.

The system calls go through `syscalls`, the one place where a test can make any step fail
(tests/files/test_atomic.py); tests/files/test_full_disk.py runs every writer on a real full
filesystem.
"""

from __future__ import annotations

import contextlib
import errno
import gc
import json
import logging
import os
import secrets
import stat
import sys
import traceback
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import cv2
import numpy as np

from stereo_gui.core.errors import InputError, StereoGuiError

log = logging.getLogger(__name__)

# what `verify` may raise to say the file does not read back
Verify = Callable[[Path], object]  # raises when the file is wrong; what it returns is not used
# a file's path as the callers give it
StrPath = str | os.PathLike[str]
# one file of write_many_atomic: (target, its data, the check of what was written or None)
AtomicItem = tuple[StrPath, bytes, Verify | None]
READ_BACK_LIMIT = 4 << 20  # bytes: files up to this size are read back and compared whole


class SystemCalls:
    """The system calls of a write, in one place so that a test can make any of them fail
    (monkeypatch an attribute of `syscalls`)."""

    open = staticmethod(os.open)
    write = staticmethod(os.write)
    fsync = staticmethod(os.fsync)
    close = staticmethod(os.close)
    replace = staticmethod(os.replace)


syscalls = SystemCalls()

_WORDS = {
    errno.ENOSPC: "No space left on device (the disk is full)",
    errno.EDQUOT: "disk quota exceeded",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.EROFS: "the file system is read-only",
    errno.EFBIG: "file too large for the file system",
    errno.EIO: "input/output error of the disk",
}


def os_error_text(exc: OSError) -> str:
    """What went wrong, in words a user reads ("permission denied", "no space left on device")."""
    words = _WORDS.get(exc.errno or -1)
    if words:
        return words
    return (exc.strerror or str(exc) or type(exc).__name__).lower()


def _kept(target: Path, existed: bool) -> str:
    return f"{target} was left as it was" if existed else "nothing was written"


def _create_temp(target: Path, folder: Path, suffix: str) -> tuple[Path, int]:
    """Create a new file in `folder`, open for writing, with the permissions the user's umask gives
    a new file (tempfile.mkstemp makes it 0600: a calibration or export would then be unreadable
    for the other technicians of the workshop). Returns its path and descriptor."""
    for _ in range(100):
        path = folder / f".{target.name}.{secrets.token_hex(4)}{suffix}"
        try:
            fd = syscalls.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                           0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise InputError(f"cannot write {target}: {os_error_text(exc)}") from exc
        return path, fd
    raise InputError(f"cannot write {target}: no free temporary file name in {folder}")


def _folder_of(target: Path) -> Path:
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {target}: folder {folder} does not exist")
    return folder


def _keep_mode(target: Path, tmp_path: Path) -> None:
    if target.is_file():  # replacing a file keeps its permissions
        os.chmod(tmp_path, stat.S_IMODE(target.stat().st_mode))


def _sync_folder(folder: Path) -> None:
    """Make the rename itself durable (best effort: not every system opens folders)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _run_verify(verify: Verify | None, tmp_path: Path, target: Path, existed: bool) -> None:
    if verify is None:
        return
    try:
        verify(tmp_path)
    except (StereoGuiError, OSError, ValueError, KeyError, TypeError, EOFError) as exc:
        detail = os_error_text(exc) if isinstance(exc, OSError) else str(exc)
        raise InputError(f"cannot write {target}: the file written does not read back "
                         f"({detail}); the disk may be full; {_kept(target, existed)}") from exc


def _commit(tmp_path: Path, target: Path, folder: Path) -> None:
    syscalls.replace(tmp_path, target)
    _sync_folder(folder)


def _prepare(target: Path, data: bytes, verify: Verify | None) -> Path:
    """Write `data` to a new temporary file beside `target` and check it; return its path."""
    view = memoryview(data).cast("B")
    folder = _folder_of(target)
    existed = target.exists()
    tmp_path, fd = _create_temp(target, folder, target.suffix or ".tmp")
    try:
        try:
            _keep_mode(target, tmp_path)
            done = 0
            while done < len(view):
                n = syscalls.write(fd, view[done:])
                if not n or n < 0:  # a write that makes no progress: the device is full
                    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
                done += n
            syscalls.fsync(fd)
        finally:
            # close even when a write failed; a close that fails loses data too
            closing, fd = fd, -1
            syscalls.close(closing)
        size = tmp_path.stat().st_size
        if size != len(view):
            raise InputError(f"cannot write {target}: {size} of {len(view)} bytes reached the "
                             f"disk; {_kept(target, existed)}")
        if len(view) <= READ_BACK_LIMIT and tmp_path.read_bytes() != view:
            raise InputError(f"cannot write {target}: the file written differs from the data; "
                             f"{_kept(target, existed)}")
        _run_verify(verify, tmp_path, target, existed)
    except OSError as exc:
        _discard(tmp_path, fd)
        raise InputError(f"cannot write {target}: {os_error_text(exc)}; "
                         f"{_kept(target, existed)}") from exc
    except BaseException:
        _discard(tmp_path, fd)
        raise
    return tmp_path


def write_bytes_atomic(target: str | os.PathLike[str], data: bytes,
                       verify: Verify | None = None) -> Path:
    """Write `data` to `target` atomically and checked (see the module doc); return the target."""
    return write_many_atomic([(target, data, verify)])[0]


def write_many_atomic(items: Iterable[AtomicItem], what: str | None = None) -> list[Path]:
    """Write several files as one: `items` are (target, data bytes, verify or None), and may be
    a generator (each file's data is made when its turn comes, so a large set is never in
    memory at once). Every file is written and checked under its temporary name before any
    target is replaced, so a full disk leaves all the old files; the renames that follow need
    no space, and should one fail, the files already replaced get their old contents back.

    `what` names the set for a person ("the simulated set in OUT"): an error then says that
    nothing of it replaced an earlier file.
    """
    prepared: list[tuple[Path, Path]] = []
    try:
        for target, data, verify in items:
            target = Path(target)
            prepared.append((_prepare(target, data, verify), target))
    except BaseException as exc:
        for tmp_path, _ in prepared:
            _discard(tmp_path, -1)
        if what is not None and isinstance(exc, InputError):
            raise InputError(f"{exc}; {what} was not written: every file it would have "
                             "replaced is as it was") from exc
        raise
    kept: list[tuple[Path, Path | None]] = []  # (target, its earlier file kept aside or None)
    for i, (tmp_path, target) in enumerate(prepared):
        folder = _folder_of(target)
        try:
            earlier = _keep_earlier(target, folder)
            kept.append((target, earlier))
            _commit(tmp_path, target, folder)
        except OSError as exc:
            for rest, _ in prepared[i:]:
                _discard(rest, -1)
            undone = _undo(kept, done=i)
            replaced = [t for t, _ in kept[:i]]
            if not replaced or undone:
                where = (f"{target} was left as it was" if not replaced else
                         f"the {len(replaced)} files already replaced have their earlier "
                         "contents again")
            else:
                where = (f"{target} was left as it was ({', '.join(map(str, replaced))} "
                         "already replaced)")
            if what is not None and (not replaced or undone):
                where += f"; {what} was not written: every file it would have replaced is as it was"
            raise InputError(f"cannot write {target}: {os_error_text(exc)}; {where}") from exc
    for _, earlier in kept:
        if earlier is not None:
            _discard(earlier, -1)
    return [target for _, target in prepared]


def _keep_earlier(target: Path, folder: Path) -> Path | None:
    """A second name (a hard link: no data is copied) for the file at `target`, so that it can
    be put back if a later file of the set cannot be renamed; None when there is no file, or
    the file system has no hard links (it cannot be put back then)."""
    if not target.is_file():
        return None
    for _ in range(100):
        path = folder / f".{target.name}.{secrets.token_hex(4)}.earlier"
        try:
            os.link(target, path)
        except FileExistsError:
            continue
        except OSError:
            return None
        return path
    return None


def _undo(kept: list[tuple[Path, Path | None]], done: int) -> bool:
    """Put back the earlier files of the first `done` targets (those new ones not in place yet
    stay as they were); True when every one is as it was."""
    ok = True
    for j, (target, earlier) in enumerate(kept):
        try:
            if j >= done:
                if earlier is not None:
                    earlier.unlink(missing_ok=True)
                continue
            if earlier is not None:
                os.replace(earlier, target)
            else:
                target.unlink(missing_ok=True)  # it did not exist before the set
        except OSError:
            ok = False
    return ok


def _discard(tmp_path: Path, fd: int) -> None:
    if fd >= 0:
        with contextlib.suppress(OSError):
            os.close(fd)
    with contextlib.suppress(OSError):
        tmp_path.unlink(missing_ok=True)


def write_text_atomic(target: StrPath, text: str, verify: Verify | None = None) -> Path:
    """Write `text` as UTF-8 atomically and checked; return the target."""
    return write_bytes_atomic(target, text.encode("utf-8"), verify)


def _verify_json(path: Path) -> None:
    json.loads(path.read_text(encoding="utf-8"))


def json_item(target: str | os.PathLike[str], doc: object) -> AtomicItem:
    """`doc` as indented JSON for `target`, parsed back before the rename: an item of
    `write_many_atomic`."""
    return (target, (json.dumps(doc, indent=2) + "\n").encode("utf-8"), _verify_json)


def write_json_atomic(target: str | os.PathLike[str], doc: object) -> Path:
    """Write `doc` as indented JSON atomically; the file is parsed back before the rename."""
    return write_bytes_atomic(*json_item(target, doc))


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike[str], suffix: str | None = None,
                verify: Verify | None = None) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; when the block is done, check the file
    (it exists, is not empty, `verify` accepts it) and rename it over the target.

    For libraries that write to a path themselves. The temporary name keeps the target's suffix
    (OpenCV and openpyxl choose the format by it). On any error the temporary file is removed and
    the target is untouched.
    """
    target = Path(target)
    folder = _folder_of(target)
    existed = target.exists()
    tmp_path, fd = _create_temp(target, folder, suffix or target.suffix or ".tmp")
    try:
        syscalls.close(fd)
        fd = -1
        _keep_mode(target, tmp_path)
        yield tmp_path
        if not tmp_path.is_file() or tmp_path.stat().st_size == 0:
            raise InputError(f"cannot write {target}: nothing reached the disk; "
                             f"{_kept(target, existed)}")
        sync_fd = syscalls.open(tmp_path, os.O_RDONLY)
        try:
            syscalls.fsync(sync_fd)
        finally:
            syscalls.close(sync_fd)
        _run_verify(verify, tmp_path, target, existed)
        _commit(tmp_path, target, folder)
    except OSError as exc:
        _release_abandoned(exc)
        _discard(tmp_path, fd)
        raise InputError(f"cannot write {target}: {os_error_text(exc)}; "
                         f"{_kept(target, existed)}") from exc
    except BaseException as exc:
        _release_abandoned(exc)
        _discard(tmp_path, fd)
        raise


def _release_abandoned(exc: BaseException) -> None:
    """Let go, now and quietly, of the file objects a library abandoned when it failed.

    openpyxl's ZipFile on a full disk raises, stays open in the frames of the traceback, and when
    the garbage collector ends it its __del__ fails again on the same disk: "Exception ignored
    in ZipFile.__del__" and a traceback on the user's terminal, long after the clear message.
    Clearing the finished frames of the traceback ends those objects here, where a failure to
    close them is logged instead.
    """
    previous = sys.unraisablehook

    def quiet(unraisable: sys.UnraisableHookArgs) -> None:
        log.debug("closing a file abandoned by a failed write failed too: %s",
                  unraisable.exc_value)

    sys.unraisablehook = quiet
    try:
        traceback.clear_frames(exc.__traceback__)
        gc.collect()
    finally:
        sys.unraisablehook = previous


def write_atomic(target: str | os.PathLike[str], writer: Callable[[Path], None],
                 verify: Verify | None = None) -> Path:
    """Call `writer(tmp_path)` and move the result over `target` atomically; return the target."""
    with atomic_path(target, verify=verify) as tmp:
        writer(tmp)
    return Path(target)


def encode_image(target: str | os.PathLike[str], image: np.ndarray) -> bytes:
    """`image` (a numpy array) encoded in the format the suffix of `target` names; InputError
    naming the target when OpenCV cannot."""
    target = Path(target)
    try:
        ok, buf = cv2.imencode(target.suffix or ".png", image)
    except cv2.error:
        ok, buf = False, None
    if not ok or buf is None:
        raise InputError(f"cannot write {target}: OpenCV could not encode the image as "
                         f"{target.suffix or 'an image'}")
    return buf.tobytes()


def write_image_atomic(target: str | os.PathLike[str], image: np.ndarray) -> Path:
    """Encode `image` (a numpy array) in the format its suffix names and write it atomically."""
    return write_bytes_atomic(target, encode_image(target, image))
