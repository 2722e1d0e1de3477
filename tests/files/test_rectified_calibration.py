"""rectified:F,B[,DOFFS] and Middlebury 2014 calib.txt: identity calibrations with a principal
point offset, triangulating Z = f B / (d + doffs)."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_gui.core.errors import CalibrationFileError, InputError
from stereo_gui.core.stereo_calibration import triangulate
from stereo_gui.files.any_calibration import load_any_calibration
from stereo_gui.files.rectified_calibration import parse_rectified_spec, read_middlebury

# Middlebury 2014 "Adirondack" (perfect), as published
ADIRONDACK = """cam0=[4161.221 0 1445.577; 0 4161.221 984.686; 0 0 1]
cam1=[4161.221 0 1654.636; 0 4161.221 984.686; 0 0 1]
doffs=209.059
baseline=176.252
width=2880
height=1988
ndisp=290
isint=0
vmin=33
vmax=218
dyavg=0
dymax=0
"""


def test_spec_with_and_without_doffs():
    assert parse_rectified_spec("rectified:700,110") == \
        parse_rectified_spec("rectified: 700 , 110 ") == parse_rectified_spec("rectified:700,110,0")
    s = parse_rectified_spec("rectified:3997.7,193.0,131.1")
    assert (s.focal_px, s.baseline_mm, s.doffs_px) == (3997.7, 193.0, 131.1)
    c = s.calibration((640, 480))
    assert c.disparity_offset_px == pytest.approx(131.1)
    assert c.P2[0, 2] - c.P1[0, 2] == pytest.approx(131.1)


@pytest.mark.parametrize("spec", ["rectified:500", "rectified:", "rectified:a,b",
                                  "rectified:1,2,3,4", "rectified:500,,3", "rectified:-3,100",
                                  "rectified:700,0", "rectified:nan,100", "rectified:1e308,1e308",
                                  "rectified:700,110,1e300"])
def test_a_malformed_spec_says_what_the_form_is(spec):
    with pytest.raises(InputError) as exc:
        parse_rectified_spec(spec)
    text = str(exc.value)
    assert spec in text or spec.split(":")[1].split(",")[0] in text
    assert "\n" not in text


def test_the_form_is_spelled_out_for_a_missing_baseline():
    with pytest.raises(InputError, match=r"rectified:F,B or rectified:F,B,DOFFS .*focal length F "
                                         r"in px, baseline B in mm"):
        parse_rectified_spec("rectified:500")


@pytest.mark.parametrize("doffs", [0.0, 24.0, -7.5])
def test_triangulation_goes_through_q_with_doffs(doffs):
    f, b = 700.0, 110.0
    c = parse_rectified_spec(f"rectified:{f},{b},{doffs}").calibration((640, 480))
    for d in (10.0, 35.5, 80.0):
        X, Y, Z = triangulate(c, 400.0, 100.0, d)
        assert Z == pytest.approx(f * b / (d + doffs))
        # X, Y through the left camera: x = f X / Z + cx
        assert 400.0 == pytest.approx(f * X / Z + c.P1[0, 2])
        assert 100.0 == pytest.approx(f * Y / Z + c.P1[1, 2])
    # a point seen at x in the left image is at x - d in the right one: the right camera's
    # projection of the triangulated point agrees (P2 holds cx + doffs)
    X, Y, Z = triangulate(c, 400.0, 100.0, 35.5)
    u = c.P2 @ np.array([X, Y, Z, 1.0])
    assert u[0] / u[2] == pytest.approx(400.0 - 35.5)


def test_middlebury_calib_txt(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text(ADIRONDACK)
    c = read_middlebury(path)
    assert c.image_size == (2880, 1988)
    assert c.focal_px == pytest.approx(4161.221)
    assert c.rectified_baseline_mm == pytest.approx(176.252)
    assert c.disparity_offset_px == pytest.approx(209.059)
    assert c.P1[0, 2] == pytest.approx(1445.577) and c.P1[1, 2] == pytest.approx(984.686)
    # Middlebury's own formula: Z = baseline * f / (d + doffs)
    _, _, Z = triangulate(c, 1000.0, 900.0, 150.0)
    assert Z == pytest.approx(176.252 * 4161.221 / (150.0 + 209.059))
    loaded = load_any_calibration(path)
    assert loaded.kind == "middlebury" and "doffs 209.059 px" in loaded.description


@pytest.mark.parametrize("edit,message", [
    (lambda t: t.replace("baseline=176.252\n", ""), "baseline= is missing"),
    (lambda t: t.replace("cam1=[4161.221 0 1654.636", "cam1=[4000 0 1654.636"), "not a rectified"),
    (lambda t: t.replace("doffs=209.059", "doffs=20"), "disagrees with the principal points"),
    (lambda t: t.replace("baseline=176.252", "baseline=far"), "baseline=far is not a number"),
    (lambda t: t.replace("width=2880", "width=-1"), "width and height"),
    (lambda t: t.replace("; 0 0 1]", "]", 1), "3x3"),
])
def test_middlebury_errors_name_the_key(tmp_path, edit, message):
    path = tmp_path / "calib.txt"
    path.write_text(edit(ADIRONDACK))
    with pytest.raises(CalibrationFileError, match=message):
        read_middlebury(path)


def test_middlebury_without_size_takes_the_images(tmp_path):
    path = tmp_path / "calib.txt"
    path.write_text(ADIRONDACK.replace("width=2880\n", "").replace("height=1988\n", ""))
    with pytest.raises(CalibrationFileError, match="width= and height="):
        read_middlebury(path)
    assert read_middlebury(path, (2880, 1988)).image_size == (2880, 1988)


@pytest.mark.parametrize("spec", ["rectified:748,110,-1000000", "rectified:748,110,5000"])
def test_a_principal_point_offset_no_matcher_can_search_is_refused_at_once(spec):
    """Refused when it is read, not 8 s later in "OverflowError ... int16" inside the matcher."""
    from stereo_gui.files.rectified_calibration import parse_rectified_spec

    with pytest.raises(InputError, match="DOFFS"):
        parse_rectified_spec(spec)
