"""Atomic writes of user data: write a temporary file next to the target, then rename it.

A crash or a full disk in the middle of a write leaves the earlier file intact.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Callable, Iterator
from pathlib import Path

from stereo_gui.core.errors import InputError


def _create_temp(target: Path, folder: Path, suffix: str) -> Path:
    """Create an empty, new file in `folder` with the permissions the user's umask gives a
    new file (tempfile.mkstemp makes it 0600: a calibration or export would then be unreadable
    for the other technicians of the workshop)."""
    for _ in range(100):
        path = folder / f".{target.name}.{secrets.token_hex(4)}{suffix}"
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                         0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise InputError(f"cannot write {target}: {exc.strerror or exc}") from exc
        os.close(fd)
        return path
    raise InputError(f"cannot write {target}: no free temporary file name in {folder}")


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; on success rename it over the target.

    The temporary name keeps the target's suffix (OpenCV and openpyxl choose the format by it).
    On any error the temporary file is removed and the target is untouched.
    """
    target = Path(target)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"cannot write {target}: folder {folder} does not exist")
    tmp_path = _create_temp(target, folder, suffix or target.suffix or ".tmp")
    try:
        if target.is_file():  # replacing a file keeps its permissions
            os.chmod(tmp_path, stat.S_IMODE(target.stat().st_mode))
        yield tmp_path
        with open(tmp_path, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp_path, target)
    except OSError as exc:
        tmp_path.unlink(missing_ok=True)
        raise InputError(f"cannot write {target}: {exc.strerror or exc}") from exc
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def write_atomic(target: str | os.PathLike, writer: Callable[[Path], None]) -> Path:
    """Call `writer(tmp_path)` and move the result over `target` atomically; return the target."""
    with atomic_path(target) as tmp:
        writer(tmp)
    return Path(target)


def write_bytes_atomic(target: str | os.PathLike, data: bytes) -> Path:
    return write_atomic(target, lambda p: p.write_bytes(data))


def write_text_atomic(target: str | os.PathLike, text: str) -> Path:
    return write_atomic(target, lambda p: p.write_text(text, encoding="utf-8"))


def write_image_atomic(target: str | os.PathLike, image) -> Path:
    """Encode `image` (a numpy array) in the format its suffix names and write it atomically."""
    import cv2

    target = Path(target)
    ok, buf = cv2.imencode(target.suffix or ".png", image)
    if not ok:
        raise InputError(f"cannot write {target}: OpenCV could not encode the image as {target.suffix}")
    return write_bytes_atomic(target, buf.tobytes())
