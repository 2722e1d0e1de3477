"""`stereo-gui target`: printable targets at true scale, refused when they do not fit the page."""

from __future__ import annotations

import re
import shutil
import subprocess

import cv2
import numpy as np
import pytest

from stereo_gui.cli import main
from stereo_gui.core.board import BoardSpec
from stereo_gui.core.detect import detect_board
from stereo_gui.files.target_sheet import PT_PER_MM


def _run(argv, capsys):
    code = main(["target", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def _pdf_shapes(data: bytes):
    """The PDF's page size (pt), its content transform and its filled rectangles (user units)."""
    text = data.decode("latin-1")
    box = [float(v) for v in re.search(r"/MediaBox \[([^\]]+)\]", text).group(1).split()]
    content = text.split("stream\n", 1)[1].split("endstream", 1)[0]
    cm = [float(v) for v in re.search(r"^(\S+) 0 0 (\S+) 0 (\S+) cm$", content, re.M).groups()]
    rects = [tuple(map(float, m.groups()))
             for m in re.finditer(r"^(\S+) (\S+) (\S+) (\S+) re f$", content, re.M)]
    return box, cm, rects, content


def test_charuco_pdf_measures_true_to_a_tenth_of_a_millimetre(tmp_path, capsys):
    out = tmp_path / "board.pdf"
    code, text, err = _run(["--type", "charuco", "--board", "7x5", "--square-mm", "30",
                            "--marker-mm", "22", "-o", out], capsys)
    assert code == 0, err
    assert "wrote" in text and "A4" in text
    data = out.read_bytes()
    assert data.startswith(b"%PDF-1.4") and data.rstrip().endswith(b"%%EOF")
    box, (sx, sy, ty), rects, content = _pdf_shapes(data)
    # the page is A4 (here turned to landscape, where the board fits), in points
    assert sorted((box[2] / PT_PER_MM, box[3] / PT_PER_MM)) == pytest.approx([210, 297], abs=0.01)
    # one user unit is one millimetre on paper
    assert abs(sx) == pytest.approx(PT_PER_MM, rel=1e-4) and abs(sy) == pytest.approx(PT_PER_MM, rel=1e-4)
    squares = [r for r in rects if abs(r[2] - 30) < 1 and abs(r[3] - 30) < 1]
    assert len(squares) == 18  # 7x5 = 35 squares, 18 of them black
    for x, y, w, h in squares:
        assert abs(w - 30.0) <= 0.1 and abs(h - 30.0) <= 0.1
        # on the board's grid: every square starts a whole number of squares from the first
        assert abs((x - squares[0][0]) / 30.0 - round((x - squares[0][0]) / 30.0)) * 30 <= 0.1
        assert abs((y - squares[0][1]) / 30.0 - round((y - squares[0][1]) / 30.0)) * 30 <= 0.1
    xs = sorted({round(x, 3) for x, *_ in squares})
    assert xs[-1] + 30 - xs[0] == pytest.approx(210.0, abs=0.1)  # 7 squares of 30 mm
    bar = [r for r in rects if abs(r[2] - 100) < 1]
    assert len(bar) == 1 and bar[0][2] == pytest.approx(100.0, abs=0.01)
    # the markers: every cell 22 mm / 6 = 3.667 mm high
    cells = [r for r in rects if r[3] < 5 and r[2] < 30]
    assert cells and all(abs(h - 22.0 / 6) < 1e-3 for *_, h in cells)
    assert "ChArUco board 7x5 squares, squares 30 mm, markers 22 mm" in content
    assert "--target charuco --board 7x5 --square-mm 30 --marker-mm 22" in content


@pytest.mark.skipif(shutil.which("pdftoppm") is None, reason="pdftoppm is not installed")
def test_the_printed_pdf_is_found_by_the_detector_at_its_true_size(tmp_path, capsys):
    out = tmp_path / "board.pdf"
    assert _run(["--type", "charuco", "--square-mm", "30", "--marker-mm", "22", "-o", out],
                capsys)[0] == 0
    subprocess.run(["pdftoppm", "-r", "300", "-gray", "-png", str(out), str(tmp_path / "page")],
                   check=True)
    img = cv2.imread(str(next(tmp_path.glob("page*.png"))), cv2.IMREAD_GRAYSCALE)
    board = BoardSpec(7, 5, 30.0, "charuco", 22.0)
    det = detect_board(img, board)
    assert det is not None and len(det.ids) == board.point_count
    grid = det.corners.reshape(4, 6, 2).astype(np.float64)
    step_mm = np.linalg.norm(np.diff(grid, axis=1), axis=2).mean() * 25.4 / 300
    assert step_mm == pytest.approx(30.0, abs=0.1)


@pytest.mark.parametrize("target, board, extra", [
    ("chessboard", "9x6", []), ("circles", "7x6", []), ("acircles", "4x11", ["--square-mm", "20"]),
    ("charuco", "7x5", ["--square-mm", "30", "--marker-mm", "22"]),
])
def test_png_targets_are_found_by_their_own_detector(tmp_path, capsys, target, board, extra):
    out = tmp_path / "t.png"
    code, _, err = _run(["--type", target, "--board", board, *extra, "--dpi", "100", "-o", out],
                        capsys)
    assert code == 0, err
    data = out.read_bytes()
    assert b"pHYs" in data[:100]  # the resolution is in the file, for printing at true size
    img = cv2.imread(str(out), cv2.IMREAD_GRAYSCALE)
    assert img.shape in ((1169, 827), (827, 1169))  # A4 at 100 dpi
    spec = BoardSpec(*map(int, board.split("x")), *(
        (30.0, target, 22.0) if target == "charuco" else
        (20.0, target) if target == "acircles" else (25.0, target)))
    det = detect_board(img, spec)
    assert det is not None and len(det.corners) == spec.point_count


def test_svg_is_in_millimetres(tmp_path, capsys):
    out = tmp_path / "t.svg"
    assert _run(["--type", "circles", "--board", "7x6", "--square-mm", "25", "-o", out],
                capsys)[0] == 0
    svg = out.read_text()
    assert 'width="210mm" height="297mm" viewBox="0 0 210 297"' in svg
    radii = {float(r) for r in re.findall(r'<circle [^>]*r="([^"]+)"', svg)}
    assert radii == {6.25}
    assert len(re.findall(r"<circle ", svg)) == 42


@pytest.mark.parametrize("argv, words", [
    (["--type", "charuco", "--board", "12x9", "--square-mm", "30", "--dict", "DICT_5X5_100"],
     "does not fit on A4"),
    (["--square-mm", "30", "--page", "b7"], "page 'b7' is not known"),
    (["--board", "9x6", "-o", "x.jpg"], "use a .pdf, .svg or .png file"),
    (["--board", "9x6", "--square-mm", "40"], "does not fit on A4"),
])
def test_targets_that_cannot_be_written_exit_2(tmp_path, capsys, argv, words):
    args = argv if "-o" in argv else [*argv, "-o", tmp_path / "t.pdf"]
    args = [str(tmp_path / a) if a == "x.jpg" else a for a in args]
    code, out, err = _run(args, capsys)
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.glob("t.*"))


def test_a_large_board_fits_a_larger_page(tmp_path, capsys):
    out = tmp_path / "big.pdf"
    code, text, err = _run(["--type", "charuco", "--board", "12x9", "--square-mm", "30",
                            "--dict", "DICT_5X5_100", "--page", "a2", "-o", out], capsys)
    assert code == 0, err
    assert "A2" in text
