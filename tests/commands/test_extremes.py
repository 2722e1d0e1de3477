"""Extreme command-line values and messages: exit 2 with one line."""

from __future__ import annotations

import errno
import subprocess
import sys
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from cli_output import one_line

from stereo_gui.cli import main


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    from stereo_gui.sources.sim import write_calibration_set

    folder = tmp_path_factory.mktemp("pair")
    write_calibration_set(folder, n_pairs=1, seed=3)
    return folder / "chessboard-L1.png", folder / "chessboard-R1.png"


def _one_line(capsys, code, *words) -> str:
    return one_line(capsys.readouterr().err, code, *words)


def test_a_2x2_board_exits_2(tmp_path, pair, capsys):
    code = main(["calibrate", str(pair[0].parent), "--board", "2x2", "--square-mm", "25",
                 "-o", str(tmp_path / "c.yaml")])
    _one_line(capsys, code, "3x3")


def test_a_folder_of_1x1_images_exits_2(tmp_path, capsys):
    for i in (1, 2):
        for side in "LR":
            cv2.imwrite(str(tmp_path / f"chessboard-{side}{i}.png"), np.zeros((1, 1), np.uint8))
    code = main(["calibrate", str(tmp_path), "--board", "9x6", "--square-mm", "25",
                 "-o", str(tmp_path / "c.yaml")])
    _one_line(capsys, code, "no chessboard")


@pytest.mark.parametrize("square", ["1e-300", "1e300"])
def test_absurd_square_sizes_exit_2(tmp_path, pair, capsys, square):
    code = _exit_code(lambda: main(["calibrate", str(pair[0].parent), "--board", "9x6",
                                    "--square-mm", square, "-o", str(tmp_path / "c.yaml")]))
    _one_line(capsys, code, "--square-mm: a number from 0.01 to 10000 mm")


@pytest.mark.parametrize("spec", ["rectified:1e308,1e308", "rectified:1e-300,1e-300"])
def test_absurd_rectified_calibrations_exit_2(tmp_path, pair, capsys, spec):
    code = main(["disparity", "--calib", spec, str(pair[0]), str(pair[1]),
                 "-o", str(tmp_path / "o.png")])
    _one_line(capsys, code, "must be a positive number of pixels")


@pytest.mark.parametrize(("params", "field"), [('{"wls_lambda": NaN}', "wls_lambda"),
                                               ('{"z_min_mm": 1e-9}', "z_min_mm")])
def test_absurd_presets_exit_2(tmp_path, pair, capsys, params, field):
    preset = tmp_path / "p.json"
    preset.write_text('{"format_version": 1, "name": "p", "params": %s}' % params)
    code = main(["disparity", "--calib", "rectified:700,110", str(pair[0]), str(pair[1]),
                 "-o", str(tmp_path / "o.png"), "--preset", str(preset)])
    _one_line(capsys, code, field)


def test_a_negative_seed_exits_2(tmp_path, capsys):
    code = _exit_code(lambda: main(["simulate", str(tmp_path / "s"), "--seed", "-1"]))
    _one_line(capsys, code, "seed")


def _exit_code(call):
    try:
        return call()
    except SystemExit as exc:
        return exc.code


@pytest.mark.parametrize("kind", ["junk-xml", "corrupted"])
def test_a_broken_workbook_exits_2_and_is_left_alone(tmp_path, pair, capsys, kind):
    book = tmp_path / "log.xlsx"
    if kind == "junk-xml":
        with zipfile.ZipFile(book, "w") as z:
            z.writestr("[Content_Types].xml", "<junk")
            z.writestr("xl/workbook.xml", "<<<")
    else:
        from stereo_gui.files.spreadsheet import write_workbook

        write_workbook(book, [])
        data = bytearray(book.read_bytes())
        data[len(data) // 2: len(data) // 2 + 200] = b"\xff" * 200
        book.write_bytes(bytes(data))
    before = book.read_bytes()
    code = main(["measure", "--calib", "rectified:700,110", str(pair[0]), str(pair[1]),
                 "--at", "320,240", "--xlsx", str(book)])
    _one_line(capsys, code, "log.xlsx")
    assert book.read_bytes() == before


def test_disparity_checks_every_output_before_writing_any(tmp_path, pair, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = main(["disparity", "--calib", "rectified:700,110", str(pair[0]), str(pair[1]),
                 "-o", "ok.png", "--npy", "nodir/x.npy"])
    _one_line(capsys, code, "nodir")
    assert not (tmp_path / "ok.png").exists()


def test_a_negative_at_value_is_explained(pair, capsys):
    code = _exit_code(lambda: main(["measure", "--calib", "rectified:700,110", str(pair[0]),
                                    str(pair[1]), "--at", "-1,5"]))
    _one_line(capsys, code, "--at=-1,5")
    code = main(["measure", "--calib", "rectified:700,110", str(pair[0]), str(pair[1]),
                 "--at=-1,5"])
    _one_line(capsys, code, "-1,5", "outside")


def test_permission_denied_is_said_as_such(tmp_path, pair, capsys, monkeypatch):
    """As root every file is readable, so the refusal of the system is made here."""
    from stereo_gui.files import calibration_file_checks

    real = np.fromfile

    def fromfile(path, *a, **k):
        if str(path) == str(pair[0]):
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        return real(path, *a, **k)

    monkeypatch.setattr(np, "fromfile", fromfile)
    code = main(["measure", "--calib", "rectified:700,110", str(pair[0]), str(pair[1]),
                 "--at", "320,240"])
    _one_line(capsys, code, "permission denied")
    monkeypatch.undo()

    calib = tmp_path / "c.yaml"
    calib.write_text("%YAML:1.0\nformat_version: 1\n")

    def deny(path, *a, **k):
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr(calibration_file_checks, "open", deny, raising=False)
    code = main(["measure", "--calib", str(calib), str(pair[0]), str(pair[1]), "--at", "1,1"])
    _one_line(capsys, code, "permission denied")


def test_opencv_log_lines_do_not_reach_the_terminal():
    """Probing a camera that is not there made OpenCV print '[ WARN:0@0.05] ... can't open
    camera by index' on every start; our own message says it instead."""
    code = ("from stereo_gui.cli import quiet_opencv; quiet_opencv(); "
            "import cv2; cv2.VideoCapture(97)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60)
    assert "[ WARN" not in done.stderr and "[ERROR" not in done.stderr, done.stderr


def test_no_zipfile_traceback_after_a_full_disk(tmp_path):
    """A file size limit makes every write past 20 kB fail as a full disk does, also inside
    openpyxl's ZipFile: our clear message, and no traceback from its __del__ after it."""
    script = f"""
import resource, signal, sys
sys.path.insert(0, {str(Path(__file__).parent.parent)!r})
from stereo_gui.files.spreadsheet import write_workbook
from stereo_gui.core.errors import StereoGuiError
path = {str(tmp_path / 'log.xlsx')!r}
from factories import make_records as rec_list
write_workbook(path, rec_list(3))
before = open(path, "rb").read()
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (20000, resource.RLIM_INFINITY))
try:
    write_workbook(path, rec_list(3000))
    print("no error")
except StereoGuiError as exc:
    print("error:", exc)
resource.setrlimit(resource.RLIMIT_FSIZE, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))
print("intact" if open(path, "rb").read() == before else "changed")
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)
    assert "error: cannot write" in done.stdout and "intact" in done.stdout, done.stdout + done.stderr
    assert "Exception ignored" not in done.stderr and "Traceback" not in done.stderr, done.stderr
