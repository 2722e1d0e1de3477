"""The second fault probe's command lines: each exits 2 with one clear line on stderr (no
traceback, no library's own warning before it, no run without end), or is refused where it was
accepted."""

from __future__ import annotations

import json
import struct
import zlib

import cv2
import numpy as np
import pytest
from cli_output import one_line

from stereo_gui.cli import main
from stereo_gui.files import images


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    from stereo_gui.sources.sim import write_calibration_set

    folder = tmp_path_factory.mktemp("pair")
    write_calibration_set(folder, n_pairs=1, seed=3)
    return folder / "chessboard-L1.png", folder / "chessboard-R1.png"


def _run(argv) -> int:
    try:
        return main([str(a) for a in argv])
    except SystemExit as exc:  # refused by the option parser
        return exc.code


def _one_line(capfd, code, *words) -> str:
    return one_line(capfd.readouterr().err, code, *words)


def _png_claiming(w: int, h: int) -> bytes:
    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0")) + chunk(b"IEND", b""))


RECTIFIED = ["--calib", "rectified:750,110"]


def _pair_args(command, left, right, tmp_path):
    if command == "measure":
        return ["measure", *RECTIFIED, left, right, "--at", "1,1"]
    if command == "disparity":
        return ["disparity", *RECTIFIED, left, right, "-o", tmp_path / "d.png"]
    return ["bench", *RECTIFIED, left, right, "--frames", "1"]


@pytest.mark.parametrize("command", ["measure", "disparity", "bench"])
def test_a_file_of_gigabytes_as_an_image(tmp_path, pair, capfd, command):
    """The probe's 2 GiB file: cv2.error ... imdecode_ and a traceback."""
    big = tmp_path / "big.png"
    with open(big, "wb") as fh:
        fh.truncate(2 << 30)  # sparse: no disk used
    code = _run(_pair_args(command, big, pair[1], tmp_path))
    _one_line(capfd, code, "big.png is 2.0 GiB", "at most 1 GiB")


@pytest.mark.parametrize("command", ["measure", "disparity", "bench"])
def test_a_header_claiming_100000_squared_pixels(tmp_path, pair, capfd, command):
    """The probe's 69 bytes: validateInputImageSize and a traceback."""
    huge = tmp_path / "huge.png"
    huge.write_bytes(_png_claiming(100_000, 100_000))
    code = _run(_pair_args(command, huge, pair[1], tmp_path))
    _one_line(capfd, code, "100000x100000 px", f"at most {images.MAX_IMAGE_SIDE_PX} px a side")


@pytest.mark.parametrize("command", ["measure", "disparity", "bench"])
def test_1x1_images(tmp_path, capfd, command):
    """The probe's: copyTo ... size() == mask.size() and a traceback."""
    for name in ("l.png", "r.png"):
        cv2.imwrite(str(tmp_path / name), np.zeros((1, 1, 3), np.uint8))
    code = _run(_pair_args(command, tmp_path / "l.png", tmp_path / "r.png", tmp_path))
    _one_line(capfd, code, "is 1x1 px: too small to match (at least 64x48 px)")


def test_a_damaged_png_gives_our_line_only(tmp_path, pair, capfd):
    """The probe: 10 clean errors printed libpng's own warnings before our line."""
    data = bytearray(pair[0].read_bytes())
    data[29] ^= 0xFF  # the header's checksum
    bad = tmp_path / "bad.png"
    bad.write_bytes(bytes(data))
    code = _run(_pair_args("measure", bad, pair[1], tmp_path))
    line = _one_line(capfd, code, "bad.png cannot be read as an image", "IHDR: CRC error")
    assert line.startswith("stereo-gui: error:")


def test_a_board_too_big_for_the_rig(tmp_path, capfd):
    """The probe's `simulate --square-mm=2000`: RuntimeError and a traceback."""
    code = _run(["simulate", tmp_path / "s", "--pairs", "2", "--square-mm=2000"])
    _one_line(capfd, code, "cannot see the 9x6, 2000 mm board whole", "give a square size")


def test_a_fit_holding_ten_to_the_400(tmp_path, pair, capfd):
    from stereo_gui.core.regression import fit_inverse, fit_to_dict

    doc = fit_to_dict(fit_inverse([(d, 82500.0 / d) for d in (30.0, 50.0, 70.0, 90.0)]))
    fit = tmp_path / "fit.json"
    fit.write_text(json.dumps(doc).replace(repr(doc["coefficients"][0]), "1" + "0" * 400, 1))
    code = _run(["measure", *RECTIFIED, *pair, "--at", "320,240", "--model", fit])
    _one_line(capfd, code, "fit.json is not usable", "beyond 1e308")


@pytest.mark.parametrize("argv, words", [
    # runs for ever
    (["bench", "--frames=99999999999999999999"], ("--frames", "from 1 to 10000")),
    (["bench", "--rounds", "1000000"], ("--rounds", "from 1 to 1000")),
    # accepted where they should be refused (simulate already refused such seeds)
    (["bench", "--accuracy", "--seed=-1"], ("--seed", "from 0 to 4294967295")),
    (["bench", "--accuracy", "--seed", "100000000000000000000"], ("--seed",)),
    (["bench", "--accuracy", "--seed", str(2**32)], ("--seed",)),
    (["simulate", "OUT", "--pairs", "1", "--square-mm", "0"], ("--square-mm", "from 0.01", "not 0")),
    (["target", "--square-mm", "0.01", "-o", "OUT/t.pdf"], ("0.01 mm", "at least 2 mm")),
    (["target", "--page", "100000x100000", "-o", "OUT/t.png"], ("at most 2000 mm",)),
    (["target", "--page", "a2", "--dpi", "2400", "-o", "OUT/t.png"], ("lower --dpi",)),
])
def test_counts_sizes_and_seeds_are_bounded(tmp_path, capfd, argv, words):
    argv = [str(tmp_path / a[4:]) if a.startswith("OUT/") else
            (str(tmp_path / "out") if a == "OUT" else a) for a in argv]
    _one_line(capfd, _run(argv), *words)
    assert not (tmp_path / "out").exists() and not list(tmp_path.glob("t.*"))


@pytest.mark.parametrize("patch", ["1000", "100000000000000000000", "0"])
def test_the_patch_is_bounded(pair, capfd, patch):
    code = _run(["measure", *RECTIFIED, *pair, "--at", "320,240", "--patch", patch])
    _one_line(capfd, code, "--patch", "from 1 to 101")


def test_alpha_minus_one_is_refused(pair, tmp_path, capfd):
    code = _run(["calibrate", pair[0].parent, "--board", "9x6", "--square-mm", "25",
                 "-o", tmp_path / "c.yaml", "--alpha=-1"])
    _one_line(capfd, code, "--alpha: a number from 0 to 1, not -1")
    assert not (tmp_path / "c.yaml").exists()
