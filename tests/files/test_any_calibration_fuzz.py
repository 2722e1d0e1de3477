"""Property tests of the readers of other tools' calibrations with hypothesis: any damaged file
gives a clean StereoGuiError or a calibration (whose matrices passed its own checks when it was
built), never another exception."""

from __future__ import annotations

import cv2
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereo_gui.core.errors import StereoGuiError
from stereo_gui.core.stereo_calibration import StereoCalibration
from stereo_gui.files.any_calibration import load_any_calibration

EXAMPLES = 100


def _seed_files(folder):
    c = StereoCalibration.identity((64, 48), 60.0, 110.0).with_updates(method="bouguet")
    out = {}
    for suffix in (".yml", ".xml"):
        path = folder / f"stereo{suffix}"
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
        for name in ("M1", "D1", "M2", "D2", "R", "T", "R1", "P2"):
            fs.write(name, c.matrices()[name])
        fs.release()
        out[suffix] = path.read_bytes()
    out[".txt"] = (b"cam0=[60 0 31.5; 0 60 23.5; 0 0 1]\ncam1=[60 0 35.5; 0 60 23.5; 0 0 1]\n"
                   b"doffs=4\nbaseline=110\nwidth=64\nheight=48\nndisp=16\n")
    return out


@st.composite
def _edited(draw, data: bytes) -> bytes:
    """`data` with one to four edits: cut short, a character replaced, a token put in, a span
    taken out."""
    b = bytearray(data)
    for _ in range(draw(st.integers(1, 4))):
        kind = draw(st.sampled_from(["cut", "replace", "insert", "delete"]))
        if kind == "insert" or not b:
            i = draw(st.integers(0, len(b)))
            b[i:i] = draw(st.sampled_from([b"nan", b"1e308", b"-", b"[", b"\n- ", b"0", b"\x00"]))
            continue
        i = draw(st.integers(0, len(b) - 1))
        if kind == "cut":
            del b[i:]
        elif kind == "replace":
            b[i] = draw(st.sampled_from(b"0123456789-.e:,;[]{} \n\x00\xffabc"))
        else:
            del b[i:i + draw(st.integers(1, 12))]
    return bytes(b)


@pytest.mark.parametrize("suffix", [".yml", ".xml", ".txt"])
def test_damaged_files_give_a_clean_error_or_a_valid_calibration(tmp_path, suffix):
    valid = _seed_files(tmp_path)[suffix]
    path = tmp_path / ("calib.txt" if suffix == ".txt" else f"fuzz{suffix}")
    loaded: list[bool] = []

    @settings(max_examples=EXAMPLES, derandomize=True, database=None, deadline=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(data=_edited(valid))
    def refused_or_valid(data: bytes) -> None:
        path.write_bytes(data)
        try:
            c = load_any_calibration(path, (64, 48)).calibration
        except StereoGuiError:
            loaded.append(False)
            return
        assert c.width > 0 and c.height > 0
        loaded.append(True)

    refused_or_valid()
    assert not all(loaded)  # the damage did break files


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
