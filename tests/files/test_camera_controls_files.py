"""The cameras' controls kept with a capture session and a calibration file: written, read back,
old files without them still load, damaged ones are left out without losing the rest."""

from __future__ import annotations

import json

import cv2
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereo_gui.core.camera_settings import CameraSettings, PairSettings
from stereo_gui.files.calibration_file import load_calibration, save_calibration
from stereo_gui.files.session import MANIFEST, CaptureSession

from factories import make_calibration

CONTROLS = PairSettings(
    CameraSettings("V4L2", focus_auto=False, focus=30.0, exposure_auto=False, exposure=156.0,
                   gain=12.0, wb_auto=False, wb_temperature=4600.0, brightness=128.0),
    CameraSettings("V4L2", focus_auto=False, focus=35.0, exposure_auto=False, exposure=170.0))


def test_the_calibration_file_keeps_the_controls_and_cv2_filestorage_reads_them(tmp_path):
    path = save_calibration(make_calibration().with_updates(camera_controls=CONTROLS),
                            tmp_path / "c.yaml")
    assert load_calibration(path).camera_controls == CONTROLS
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    try:
        left = fs.getNode("camera_controls").getNode("left")
        assert left.getNode("focus").real() == 30.0 and left.getNode("backend").string() == "V4L2"
        assert int(left.getNode("focus_auto").real()) == 0
        assert fs.getNode("M1").mat().shape == (3, 3)  # the sample's names are untouched
    finally:
        fs.release()


def test_a_calibration_file_without_controls_loads_as_before(tmp_path):
    path = save_calibration(make_calibration(), tmp_path / "c.yaml")
    assert "camera_controls" not in path.read_text()
    assert load_calibration(path).camera_controls is None


def test_damaged_controls_are_left_out_and_the_calibration_still_loads(tmp_path, caplog):
    path = save_calibration(make_calibration().with_updates(camera_controls=CONTROLS),
                            tmp_path / "c.yaml")
    text = path.read_text().replace("focus: 35.", "focus: near")
    path.write_text(text)
    calib = load_calibration(path)
    assert calib.camera_controls is None and calib.M1.shape == (3, 3)
    assert "controls of this calibration are not known" in caplog.text


def test_the_session_keeps_the_controls_its_pairs_were_taken_with(tmp_path):
    s = CaptureSession.create(tmp_path / "s")
    assert s.camera_controls is None
    s.set_camera_controls(CONTROLS)
    again = CaptureSession.open(tmp_path / "s")
    assert again.camera_controls == CONTROLS
    assert again.calibration_controls() == CONTROLS
    again.set_swapped(True)  # the cameras were found swapped: a calibration names them so
    assert again.calibration_controls() == CONTROLS.swapped()


def test_an_older_session_without_controls_opens(tmp_path):
    CaptureSession.create(tmp_path / "s")
    data = json.loads((tmp_path / "s" / MANIFEST).read_text())
    assert "camera_controls" not in data
    assert CaptureSession.open(tmp_path / "s").camera_controls is None


def test_damaged_session_controls_are_a_warning_not_a_lost_session(tmp_path):
    s = CaptureSession.create(tmp_path / "s")
    s.set_camera_controls(CONTROLS)
    path = tmp_path / "s" / MANIFEST
    data = json.loads(path.read_text())
    data["camera_controls"]["left"]["focus_auto"] = "sometimes"
    path.write_text(json.dumps(data))
    again = CaptureSession.open(tmp_path / "s")
    assert again.has_manifest and again.camera_controls is None
    assert any("controls of this session are not known" in w for w in again.warnings)


@pytest.mark.parametrize("swapped", [False, True])
def test_the_calibrate_command_carries_the_sessions_controls(tmp_path, capsys, swapped):
    from stereo_gui.cli import main
    from stereo_gui.sources.sim import write_calibration_set

    (tmp_path / "set").mkdir()
    folder = write_calibration_set(tmp_path / "set", n_pairs=8, seed=5)
    s = CaptureSession.open(folder)
    s.set_camera_controls(CONTROLS)
    if swapped:
        s.set_swapped(True)
    code = main(["calibrate", str(folder), "--board", "9x6", "--square-mm", "25", "-o",
                 str(tmp_path / "c.yaml"), "--min-pairs", "4"])
    assert code == 0, capsys.readouterr().err
    got = load_calibration(tmp_path / "c.yaml").camera_controls
    assert got == (CONTROLS.swapped() if swapped else CONTROLS)



JSON = st.recursive(
    st.none() | st.booleans() | st.floats(allow_nan=True) | st.integers() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(
        st.sampled_from(["left", "right", "backend", "focus", "focus_auto", "exposure", "gain",
                         "x"]), inner, max_size=5),
    max_leaves=20)


@settings(max_examples=300, deadline=None)
@given(JSON)
def test_any_json_gives_settings_or_a_clean_error(data):
    try:
        s = PairSettings.from_json(data)
    except ValueError:
        return
    assert PairSettings.from_json(s.to_json()) == s
