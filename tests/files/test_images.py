"""Image files: sizes from the header before any decoding, limits said in the error, the
decoders' own complaints kept off the terminal."""

from __future__ import annotations

import os
import struct
import zlib

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import InputError
from stereo_gui.files import images
from stereo_gui.files.images import header_size, read_image_file


def _chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def png_claiming(w: int, h: int) -> bytes:
    """A small PNG whose header claims w x h pixels (the probe's was 69 bytes)."""
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr)
            + _chunk(b"IDAT", zlib.compress(b"\0")) + _chunk(b"IEND", b""))


@pytest.mark.parametrize("ext", [".png", ".jpg", ".bmp", ".tif", ".webp", ".ppm", ".pgm"])
@pytest.mark.parametrize("size", [(64, 48), (641, 479), (3, 1000)])
def test_the_header_gives_the_size_of_every_format_we_read(ext, size):
    w, h = size
    img = np.random.default_rng(w).integers(0, 255, (h, w, 3), np.uint8)
    if ext == ".pgm":
        img = img[..., 0]
    ok, buf = cv2.imencode(ext, img)
    assert ok
    assert header_size(buf) == (w, h)


def test_a_header_claiming_100000_squared_is_refused_before_decoding(tmp_path, monkeypatch):
    path = tmp_path / "huge.png"
    path.write_bytes(png_claiming(100_000, 100_000))
    decoded = []
    monkeypatch.setattr(images.cv2, "imdecode", lambda *a: decoded.append(a))
    with pytest.raises(InputError, match=r"huge.png is 100000x100000 px: larger than this "
                                         r"program reads \(at most 10000 px a side"):
        read_image_file(path)
    assert decoded == []


def test_a_real_image_beyond_the_limit_is_refused_at_once(tmp_path):
    """An image larger than the limit is refused from its header, not decoded (a 30000x30000
    PNG takes more than 60 s)."""
    path = tmp_path / "big.png"
    cv2.imwrite(str(path), np.zeros((12_000, 200), np.uint8))
    with pytest.raises(InputError, match="200x12000 px: larger than"):
        read_image_file(path)


def test_a_file_of_gigabytes_is_refused_without_reading_it(tmp_path):
    path = tmp_path / "big.png"
    with open(path, "wb") as fh:
        fh.truncate(images.MAX_IMAGE_BYTES + 1)  # sparse: no disk used
    with pytest.raises(InputError, match=r"big.png is 1.0 GiB: larger than any image this "
                                         r"program reads \(at most 1 GiB\)"):
        read_image_file(path, name="left image big.png")


def test_a_format_without_a_header_we_read_is_checked_after_decoding(tmp_path, monkeypatch):
    monkeypatch.setattr(images, "MAX_IMAGE_SIDE_PX", 100)
    path = tmp_path / "wide.hdr"  # Radiance HDR: no header parsed here
    cv2.imwrite(str(path), np.ones((20, 150, 3), np.float32))
    assert header_size(path.read_bytes()) is None
    with pytest.raises(InputError, match="150x20 px: larger than"):
        read_image_file(path, cv2.IMREAD_UNCHANGED)


def _png(tmp_path):
    path = tmp_path / "ok.png"
    cv2.imwrite(str(path), np.random.default_rng(0).integers(0, 255, (48, 64, 3), np.uint8))
    return path.read_bytes()


def test_a_damaged_png_is_said_in_one_error_without_libpng_on_the_terminal(tmp_path, capfd):
    good = _png(tmp_path)
    bad = bytearray(good)
    bad[29] ^= 0xFF  # the header's checksum
    (tmp_path / "crc.png").write_bytes(bytes(bad))
    with pytest.raises(InputError, match=r"crc.png cannot be read as an image \(the decoder "
                                         r"says: IHDR: CRC error\)"):
        read_image_file(tmp_path / "crc.png")
    (tmp_path / "cut.png").write_bytes(good[: len(good) // 3])
    with pytest.raises(InputError, match=r"cut.png cannot be read as an image"):
        read_image_file(tmp_path / "cut.png")
    assert "libpng" not in capfd.readouterr().err


def test_a_png_with_a_bad_colour_profile_reads_quietly(tmp_path, capfd):
    good = _png(tmp_path)
    at = good.index(b"IDAT") - 4
    path = tmp_path / "iccp.png"
    path.write_bytes(good[:at] + _chunk(b"iCCP", b"icc\0\0" + zlib.compress(b"x" * 200))
                     + good[at:])
    assert read_image_file(path).shape == (48, 64, 3)
    assert "libpng" not in capfd.readouterr().err


def test_other_writes_to_stderr_meanwhile_still_reach_it(capfd):
    caught: list[str] = []
    with images.library_noise_caught(caught):
        os.write(2, b"libpng warning: iCCP: too short\n")
        os.write(2, b"stereo-gui: warning: a camera stopped\n")
    err = capfd.readouterr().err
    assert caught == ["libpng warning: iCCP: too short"]
    assert "a camera stopped" in err and "libpng" not in err

