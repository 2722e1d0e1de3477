"""Seeded mutation fuzzing of the readers of other tools' calibrations: any input gives a clean
StereoGuiError or a calibration whose matrices pass the checks, never another exception."""

from __future__ import annotations

import random

import cv2
import numpy as np
import pytest

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.stereo_calibration import MATRIX_SHAPES, StereoCalibration, check_matrices
from stereo_gui.files.any_calibration import load_any_calibration

CASES = 120


def _seed_files(folder):
    c = StereoCalibration.identity((64, 48), 60.0, 110.0).with_updates(method="bouguet")
    out = {}
    for suffix in (".yml", ".xml"):
        path = folder / f"stereo{suffix}"
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        for name in ("M1", "D1", "M2", "D2", "R", "T", "R1", "P2"):
            fs.write(name, np.asarray(getattr(c, name)))
        fs.release()
        out[suffix] = path.read_bytes()
    out[".txt"] = (b"cam0=[60 0 31.5; 0 60 23.5; 0 0 1]\ncam1=[60 0 35.5; 0 60 23.5; 0 0 1]\n"
                   b"doffs=4\nbaseline=110\nwidth=64\nheight=48\nndisp=16\n")
    return out


def _mutate(data: bytes, rng: random.Random) -> bytes:
    b = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        kind = rng.random()
        if kind < 0.3 and b:
            del b[rng.randrange(len(b)):]  # truncation
        elif kind < 0.6 and b:
            b[rng.randrange(len(b))] = rng.choice(b"0123456789-.e:,;[]{} \n\x00\xffabc")
        elif kind < 0.8:
            b[rng.randrange(len(b) + 1):0] = rng.choice([b"nan", b"1e308", b"-", b"[", b"\n- ",
                                                         b"0", b"\x00"])
        elif b:
            i = rng.randrange(len(b))
            del b[i:i + rng.randint(1, 12)]
    return bytes(b)


@pytest.mark.parametrize("suffix", [".yml", ".xml", ".txt"])
def test_mutated_files_give_a_clean_error_or_a_valid_calibration(tmp_path, suffix):
    seeds = _seed_files(tmp_path)
    rng = random.Random(1234 + len(suffix))
    name = "calib.txt" if suffix == ".txt" else f"fuzz{suffix}"
    ok = 0
    for i in range(CASES):
        path = tmp_path / name
        path.write_bytes(_mutate(seeds[suffix], rng))
        try:
            loaded = load_any_calibration(path, (64, 48))
        except StereoGuiError:
            continue
        c = loaded.calibration
        check_matrices({k: getattr(c, k) for k in MATRIX_SHAPES} | {"D1": c.D1, "D2": c.D2},
                       f"case {i}")
        assert c.width > 0 and c.height > 0
        ok += 1
    assert ok < CASES  # the mutations did break files


@pytest.mark.parametrize("edit,message", [
    (lambda t: t.replace("   cols: 3\n", "", 1), "needs rows and cols"),
    (lambda t: t.replace("   rows: 3\n", "   rows: 9\n", 1), "announces 9x3 values but holds 9"),
    (lambda t: t.replace("   rows: 3\n", "   rows: 99999999999\n", 1), "announces"),
    (lambda t: t.replace("dt: d", "dt: q", 1), "dt"),
    (lambda t: t.replace("   cols: 3\n", "   cols: 0\n", 1), "at least 1"),
])
def test_a_matrix_header_that_disagrees_with_its_data_is_refused_before_opencv_reads_it(
        tmp_path, edit, message):
    """FileNode.mat() copies the data into the matrix the header announces before it checks
    them: a lost 'cols' line overran the heap and aborted the process later."""
    text = _seed_files(tmp_path)[".yml"].decode()
    path = tmp_path / "stereo.yml"
    path.write_text(edit(text))
    for _ in range(20):  # a heap overrun shows only after a while
        with pytest.raises(StereoGuiError, match=message):
            load_any_calibration(path, (64, 48))
