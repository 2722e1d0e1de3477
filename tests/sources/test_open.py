"""Source specs: parsing, dispatch, and the automatic fallback to the simulated rig."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from fake_cameras import PresentCapture

import stereo_gui.sources.cameras as cameras
from stereo_gui.core.errors import InputError, SourceError
from stereo_gui.sources.cameras import CameraInfo, TwoCameraSource
from stereo_gui.sources.open import OpenedSource, open_source, parse_source_spec
from stereo_gui.sources.sim import SimSource


@pytest.mark.parametrize("spec, kind, indices", [
    (None, "auto", ()), ("auto", "auto", ()), ("", "auto", ()), ("sim", "sim", ()),
    ("cams:0,1", "cams", (0, 1)), ("cams: 2 , 0", "cams", (2, 0)), ("sbs:3", "sbs", (3,)),
])
def test_parse_specs(spec, kind, indices):
    s = parse_source_spec(spec)
    assert (s.kind, s.indices) == (kind, indices)


def test_parse_sim_modes_and_paths(tmp_path):
    assert parse_source_spec("sim:board").mode == "board"
    assert parse_source_spec(str(tmp_path)).kind == "folder"
    video = tmp_path / "v.avi"
    video.write_bytes(b"x")
    assert parse_source_spec(str(video)).kind == "video"


@pytest.mark.parametrize("spec, words", [
    ("cams:0", "cams:L,R"), ("cams:a,b", "cams:L,R"), ("cams:1,1", "different"),
    ("sbs:", "sbs:N"), ("sbs:1,2", "sbs:N"), ("/no/such/folder", "neither an existing folder"),
    ("camera", "neither an existing folder"),
])
def test_bad_specs_say_what_is_expected(spec, words):
    with pytest.raises(InputError, match=words) as exc:
        parse_source_spec(spec)
    assert "\n" not in str(exc.value)
    with pytest.raises(InputError):
        open_source(spec)


def test_sim_source(tmp_path):
    opened = open_source("sim:scene")
    assert isinstance(opened, OpenedSource) and not opened.fell_back_to_sim
    assert isinstance(opened.source, SimSource) and opened.source.mode == "scene"
    a = opened.source.read()
    swapped = open_source("sim:scene", swap=True).source
    b = swapped.read()
    np.testing.assert_array_equal(a.left, b.right)
    np.testing.assert_array_equal(a.right, b.left)
    assert "swapped" in swapped.name and swapped.mode == "scene"  # attributes pass through
    small = open_source("sim:scene", size=(320, 240)).source.read()
    assert small.left.shape == (240, 320, 3)
    with pytest.raises(InputError):
        open_source("sim", size=(0, 480))


def test_auto_falls_back_to_sim_without_cameras(monkeypatch):
    monkeypatch.setattr(cameras, "list_cameras", lambda: [])
    opened = open_source("auto")
    assert opened.fell_back_to_sim and isinstance(opened.source, SimSource)
    assert "no cameras were found" in opened.message
    monkeypatch.setattr(cameras, "list_cameras", lambda: [CameraInfo(0, "Webcam", "/dev/video0")])
    opened = open_source(None)
    assert opened.fell_back_to_sim and "only one camera" in opened.message and "Webcam" in opened.message


_Cap = PresentCapture


def test_auto_uses_two_cameras_or_says_why_not(monkeypatch):
    monkeypatch.setattr(cameras.cv2, "VideoCapture", _Cap)
    listed = [CameraInfo(2, "Left cam", "/dev/video2"), CameraInfo(4, "Right cam", "/dev/video4")]
    monkeypatch.setattr(cameras, "list_cameras", lambda: listed)
    _Cap.present = {2, 4}
    opened = open_source("auto", swap=True)
    assert not opened.fell_back_to_sim and isinstance(opened.source, TwoCameraSource)
    assert "Left cam" in opened.message
    f = opened.source.read()
    assert (f.left[0, 0, 0], f.right[0, 0, 0]) == (4, 2)
    # listed but not openable (another program holds one): the simulated rig, and why
    _Cap.present = {2}
    opened = open_source("auto")
    assert opened.fell_back_to_sim and "could not be opened" in opened.message
    assert "camera 4" in opened.message


def test_explicit_cameras_do_not_fall_back(monkeypatch):
    monkeypatch.setattr(cameras.cv2, "VideoCapture", _Cap)
    _Cap.present = {0, 1}
    src = open_source("cams:1,0").source
    assert src.read().left[0, 0, 0] == 1
    sbs = open_source("sbs:0", size=(32, 48)).source
    assert sbs.read().left.shape == (48, 32, 3)
    _Cap.present = set()
    with pytest.raises(SourceError, match="cannot open left camera 0"):
        open_source("cams:0,1")


def test_video_and_folder_specs(tmp_path):
    video = tmp_path / "sbs.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter.fourcc(*"MJPG"), 10.0, (64, 24))
    for _ in range(2):
        writer.write(np.zeros((24, 64, 3), np.uint8))
    writer.release()
    from stereo_gui.sources import playback

    src = open_source(str(video)).source  # played back with pause, step and loop
    assert isinstance(src, playback.PlaybackSource) and src.read().left.shape == (24, 32, 3)
    assert src.frame_count == 2
    src.close()
    for n in (1, 2):
        for side in "LR":
            cv2.imwrite(str(tmp_path / f"chessboard-{side}{n}.png"), np.full((24, 32, 3), n, np.uint8))
    opened = open_source(str(tmp_path))
    assert isinstance(opened.source, playback.PlaybackSource) and not opened.fell_back_to_sim
    opened.source.close()


def test_a_relative_folder_or_video_is_remembered_absolute(tmp_path, monkeypatch):
    for side in "LR":
        cv2.imwrite(str(tmp_path / f"chessboard-{side}1.png"), np.zeros((24, 32, 3), np.uint8))
    monkeypatch.chdir(tmp_path.parent)
    opened = open_source(tmp_path.name)
    opened.source.close()
    assert opened.spec == str(tmp_path.resolve())


def test_remembered_cameras_are_found_under_their_new_index(monkeypatch):
    """A webcam unplugged and plugged in again comes back under another index: the remembered
    name and USB ids find it; each camera opens with the backend the listing reports."""
    monkeypatch.setattr(cameras.cv2, "VideoCapture", _Cap)
    listed = [CameraInfo(0, "HD Webcam C270", "/dev/video0", cv2.CAP_V4L2, 0x046D, 0x0825),
              CameraInfo(6, "USB2.0 Camera", "/dev/video6", cv2.CAP_V4L2, 0x1908, 0x2311)]
    monkeypatch.setattr(cameras, "list_cameras", lambda: listed)
    _Cap.present = {0, 6}
    remembered = (listed[0].identity, listed[1].identity)
    opened = open_source("cams:0,2", remembered_cameras=remembered)
    assert opened.spec == "cams:0,6" and opened.cameras == remembered
    assert "is now at index 6 (was 2)" in opened.message
    f = opened.source.read()
    assert (f.left[0, 0, 0], f.right[0, 0, 0]) == (0, 6)
    opened.source.close()
    # nothing remembered: the indices as given, their identities recorded for the next time
    opened = open_source("cams:6,0")
    assert opened.spec == "cams:6,0" and opened.cameras == (remembered[1], remembered[0])
    opened.source.close()
    opened = open_source("sbs:2", remembered_cameras=(remembered[1],))
    assert opened.spec == "sbs:6"
    opened.source.close()


def test_falling_back_to_the_simulated_rig_is_said_as_a_warning(monkeypatch, caplog):
    """Without -v only warnings reach the terminal: the fallback must be one."""
    import logging

    monkeypatch.setattr(cameras, "list_cameras", lambda: [])
    with caplog.at_level(logging.WARNING, logger="stereo_gui.sources.open"):
        opened = open_source("auto", size=(160, 120))
    assert opened.fell_back_to_sim
    warned = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert warned and "showing the simulated rig" in warned[0].getMessage()
    assert "no cameras were found" in warned[0].getMessage()


def test_sim_wall_specs():
    s = parse_source_spec("sim:wall")
    assert (s.kind, s.mode, s.condition, s.wall_mm) == ("sim", "wall", "rig", 1000.0)
    s = parse_source_spec("Sim:Wall:webcams:2.5")
    assert (s.condition, s.wall_mm) == ("webcams", 2500.0)
    assert parse_source_spec("sim:wall:weak").wall_mm == 1000.0


@pytest.mark.parametrize("spec, words", [
    ("sim:wall:paint", "choose one of rig, weak"), ("sim:wall:weak:0.1", "from 0.4 to 8"),
    ("sim:wall:weak:far", "in metres"), ("sim:wall:weak:nan", "in metres"),
    ("sim:wall:weak:1:2", "in metres"),
])
def test_bad_sim_wall_specs_name_the_choices(spec, words):
    with pytest.raises(InputError, match=words) as exc:
        parse_source_spec(spec)
    assert "\n" not in str(exc.value)


def test_sim_wall_source_shows_the_wall_under_its_condition():
    from stereo_gui.sources.sim.conditions import CONDITIONS

    src = open_source("sim:wall:webcams:1.5", size=(320, 240)).source
    assert isinstance(src, SimSource) and src.condition is CONDITIONS["webcams"]
    assert "1.5 m" in src.name and "MJPG" in src.name
    f = src.read()
    assert f.truth.pose is None  # no chessboard in front of the wall
    calib = src.rig.true_calibration()
    w, h = calib.image_size
    assert f.truth.point_rectified(calib, w / 2, h / 2)[2] == pytest.approx(1500.0, rel=0.01)
    gray = [cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32) for img in (f.left, f.right)]
    centre = [float(g[h // 3:2 * h // 3, w // 3:2 * w // 3].mean()) for g in gray]
    corner = float(gray[0][:h // 8, :w // 8].mean())
    assert corner < 0.85 * centre[0]  # vignetting: the corners 35 % darker at the very corner
    assert centre[1] < centre[0] - 8  # the right camera's gain 0.8 (black level +12)
    # a smooth painted wall at half contrast: little texture left in the middle
    assert float(gray[0][h // 3:2 * h // 3, w // 3:2 * w // 3].std()) < 6.0
    rich = open_source("sim:wall:rig:1.5", size=(320, 240)).source.read()
    rich_gray = cv2.cvtColor(rich.left, cv2.COLOR_BGR2GRAY).astype(np.float32)
    assert float(rich_gray[h // 3:2 * h // 3, w // 3:2 * w // 3].std()) > 12.0
