"""Camera sources without cameras: a fake cv2.VideoCapture, a fake sysfs, a video written here."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

import stereo_gui.sources.cameras as cameras
from stereo_gui.core.errors import SourceError, SourceUnavailable
from stereo_gui.sources.cameras import (
    CameraInfo, EndOfSource, SideBySideSource, TwoCameraSource, VideoFileSource, list_cameras,
    split_side_by_side,
)

from fake_cameras import FakeCapture, unplug  # tests/fake_cameras.py


@pytest.fixture
def fake_cams(monkeypatch):
    """The fake devices (`devices`, `log`); `opened` lists every capture opened, in order."""
    FakeCapture.devices = {0: {"value": 10}, 1: {"value": 100}}
    FakeCapture.log = []
    opened = []

    def capture(index, *args):
        opened.append(FakeCapture(index, *args))
        return opened[-1]

    monkeypatch.setattr(FakeCapture, "opened", opened, raising=False)
    monkeypatch.setattr(cameras.cv2, "VideoCapture", capture)
    return FakeCapture


def test_two_cameras_grab_both_then_retrieve(fake_cams):
    src = TwoCameraSource(0, 1, size=(64, 48))
    # the capabilities it has and has not (FrameSource's "none" answers, its own controls)
    assert src.camera_controls() is not None
    assert src.playback() is None and src.simulated_rig() is None
    assert src.name == "Cameras 0, 1" and src.nominal_fps == 25.0
    fake_cams.log.clear()
    f0 = src.read()
    assert fake_cams.log == [("grab", 0), ("grab", 1), ("retrieve", 0), ("retrieve", 1)]
    f1 = src.read()
    assert (f0.index, f1.index) == (0, 1)
    assert f0.left[0, 0, 0] == 11 and f0.right[0, 0, 0] == 101
    assert f0.t_left <= f0.t_right <= f1.t_left <= f1.t_right
    # the requested size (and MJPG) was asked of both devices
    cap = fake_cams.opened[0]
    assert cap.index == 0 and cap.props[cv2.CAP_PROP_FRAME_WIDTH] == 64 and cap.props[cv2.CAP_PROP_FRAME_HEIGHT] == 48
    # a grab of a camera that stops answering fails after a while instead of blocking for ever
    assert cap.props[cv2.CAP_PROP_READ_TIMEOUT_MSEC] == cameras.READ_TIMEOUT_MS
    src.close()
    src.close()
    assert all(c == ("release", i) for c, i in zip(fake_cams.log[-2:], (0, 1)))
    with pytest.raises(SourceError):
        src.read()


def test_swap_exchanges_the_cameras(fake_cams):
    src = TwoCameraSource(0, 1, swap=True)
    f = src.read()
    assert f.left[0, 0, 0] == 101 and f.right[0, 0, 0] == 11
    assert src.name == "Cameras 1, 0"


def test_a_dropped_frame_is_retried(fake_cams):
    fake_cams.devices[1]["drop"] = (1,)
    f = TwoCameraSource(0, 1).read()
    assert f.right[0, 0, 0] == 102  # the second grab


def test_camera_that_disappears_says_it_is_reconnecting(fake_cams, monkeypatch):
    monkeypatch.setattr(cameras, "list_cameras", lambda: [])
    fake_cams.devices[1]["dead_after"] = 2
    src = TwoCameraSource(0, 1)
    src.read()
    src.read()
    with pytest.raises(SourceUnavailable, match=r"Reconnecting to right camera 1….*stopped "
                                                r"delivering frames.*every 3 s"):
        src.read()
    right = [c for c in fake_cams.opened if c.index == 1]
    assert right[-1].released and fake_cams.log[-1] == ("release", 1)


class Clock:
    """time.monotonic and Event.wait of the camera module, moved by hand (no test waits)."""

    def __init__(self, monkeypatch):
        self.t = 100.0
        monkeypatch.setattr(cameras.time, "monotonic", lambda: self.t)
        monkeypatch.setattr(cameras, "UNAVAILABLE_WAIT_S", 0.0)


def listing(*cams):
    """A list_cameras() stand-in over (index, name) pairs, counting its calls."""
    def list_fn():
        list_fn.calls += 1
        return [CameraInfo(i, name, f"/dev/video{i}", None, 0x046D, 0x0825)
                for i, name in list_fn.present]

    list_fn.calls = 0
    list_fn.present = list(cams)
    return list_fn


def test_one_undecodable_frame_is_skipped_and_counted(fake_cams):
    fake_cams.devices[1]["undecodable"] = (2,)
    src = TwoCameraSource(0, 1)
    frames = [src.read() for _ in range(3)]
    assert [f.index for f in frames] == [0, 1, 2]
    # the second pair was left out: the frames read are grabs 1, 3 and 4 of both cameras
    assert [int(f.right[0, 0, 0]) for f in frames] == [101, 103, 104]
    assert [int(f.left[0, 0, 0]) for f in frames] == [11, 13, 14]
    assert src.skipped_frames == 1 and src.reconnects == 0


def test_a_camera_that_only_delivers_undecodable_frames_is_reconnected(fake_cams, monkeypatch):
    monkeypatch.setattr(cameras, "list_cameras", lambda: [])
    fake_cams.devices[0]["undecodable"] = range(1, 100)
    src = TwoCameraSource(0, 1)
    with pytest.raises(SourceUnavailable, match="left camera 0.*cannot be decoded"):
        src.read()
    assert src.skipped_frames == cameras.MAX_FAILED_GRABS


def test_a_vanished_camera_is_looked_for_every_few_seconds_and_resumes(fake_cams, monkeypatch):
    clock = Clock(monkeypatch)
    c270 = "HD Webcam C270 [046d:0825]"
    cams = listing((0, "HD Webcam C270"), (1, "HD Webcam C270"))
    monkeypatch.setattr(cameras, "list_cameras", cams)
    for dev in fake_cams.devices.values():
        dev["size"] = (80, 60)
    src = TwoCameraSource(0, 1, size=(80, 60), identities=(c270, c270))
    assert src.read().right.shape == (60, 80, 3)
    unplug(fake_cams.devices, 1)
    cams.present = [(0, "HD Webcam C270")]
    with pytest.raises(SourceUnavailable, match=r"Reconnecting to right camera 1 \(HD Webcam"):
        src.read()
    # before RECONNECT_INTERVAL_S nothing is looked for: reads return at once, saying so
    clock.t += cameras.RECONNECT_INTERVAL_S - 0.5
    with pytest.raises(SourceUnavailable, match="Reconnecting to right camera 1"):
        src.read()
    assert cams.calls == 0
    clock.t += 1.0  # time to look: not listed yet, so not opened
    with pytest.raises(SourceUnavailable):
        src.read()
    assert cams.calls == 1
    # plugged in again: found at the next look, opened at the size it had, frames go on
    fake_cams.devices[1] = {"value": 200, "size": (80, 60)}
    cams.present = [(0, "HD Webcam C270"), (1, "HD Webcam C270")]
    with pytest.raises(SourceUnavailable):
        src.read()  # still within the interval
    clock.t += cameras.RECONNECT_INTERVAL_S
    f = src.read()
    assert cams.calls == 2 and src.reconnects == 1
    assert f.right.shape == (60, 80, 3) and f.right[0, 0, 0] == 201 and f.index == 1
    cap = fake_cams.opened[-1]  # the right camera, opened again
    assert cap.index == 1 and not cap.released
    assert (cap.props[cv2.CAP_PROP_FRAME_WIDTH], cap.props[cv2.CAP_PROP_FRAME_HEIGHT]) == (80, 60)
    assert src.name == "Cameras 0, 1"


def test_a_camera_back_under_another_index_is_found_by_name_not_its_twin(fake_cams, monkeypatch):
    """Two identical webcams: the right one comes back at index 4, and the left one, still at
    0 with the same name and USB ids, is not taken for it."""
    clock = Clock(monkeypatch)
    c270 = "HD Webcam C270 [046d:0825]"
    cams = listing((0, "HD Webcam C270"), (2, "HD Webcam C270"))
    monkeypatch.setattr(cameras, "list_cameras", cams)
    fake_cams.devices[2] = fake_cams.devices.pop(1)
    src = TwoCameraSource(0, 2, identities=(c270, c270))
    src.read()
    unplug(fake_cams.devices, 2)
    cams.present = [(0, "HD Webcam C270"), (3, "Other camera")]
    fake_cams.devices[3] = {"value": 30}
    with pytest.raises(SourceUnavailable):
        src.read()
    clock.t += cameras.RECONNECT_INTERVAL_S
    with pytest.raises(SourceUnavailable):
        src.read()  # another camera is listed; it is not opened in its place
    assert 3 not in [c.index for c in fake_cams.opened]
    fake_cams.devices[4] = {"value": 150}
    cams.present = [(0, "HD Webcam C270"), (3, "Other camera"), (4, "HD Webcam C270")]
    clock.t += cameras.RECONNECT_INTERVAL_S
    f = src.read()
    assert f.left[0, 0, 0] > 10 and f.right[0, 0, 0] == 151
    assert src.name == "Cameras 0, 4" and src.right_index == 4


def test_a_camera_back_with_another_image_size_stops_the_source(fake_cams, monkeypatch):
    clock = Clock(monkeypatch)
    cams = listing((0, "A"), (1, "B"))
    monkeypatch.setattr(cameras, "list_cameras", cams)
    src = TwoCameraSource(0, 1, identities=("A [046d:0825]", "B [046d:0825]"))
    src.read()
    for i in (0, 1):
        unplug(fake_cams.devices, i)
    with pytest.raises(SourceUnavailable, match="left camera 0 .*and right camera 1"):
        src.read()
    fake_cams.devices.update({0: {"value": 1, "size": (32, 24)}, 1: {"value": 2, "size": (32, 24)}})
    clock.t += cameras.RECONNECT_INTERVAL_S
    with pytest.raises(SourceError, match="32x24 px images now, not 64x48") as err:
        src.read()
    assert not isinstance(err.value, SourceUnavailable)


def test_closing_ends_a_reconnecting_source(fake_cams, monkeypatch):
    monkeypatch.setattr(cameras, "list_cameras", lambda: [])
    src = TwoCameraSource(0, 1)
    unplug(fake_cams.devices, 0)
    with pytest.raises(SourceUnavailable):
        src.read()
    src.close()
    with pytest.raises(SourceError, match="closed"):
        src.read()


def test_cannot_open_raises_and_releases_the_other(fake_cams):
    with pytest.raises(SourceError, match="cannot open right camera 7"):
        TwoCameraSource(0, 7)
    assert ("release", 0) in fake_cams.log
    with pytest.raises(SourceError, match="same device"):
        TwoCameraSource(1, 1)


def test_gray_frames_become_bgr_and_sizes_must_match(fake_cams):
    fake_cams.devices[0]["gray"] = True
    f = TwoCameraSource(0, 1).read()
    assert f.left.shape == (48, 64, 3)
    fake_cams.devices[1]["size"] = (32, 24)
    with pytest.raises(SourceError, match="different image sizes"):
        TwoCameraSource(0, 1).read()


def test_nonexistent_real_device_raises_source_error():
    """The real cv2.VideoCapture: an index with no device fails at once with a clear message."""
    with pytest.raises(SourceError, match="cannot open left camera 97"):
        TwoCameraSource(97, 98)
    with pytest.raises(SourceError, match="cannot open side-by-side camera 96"):
        SideBySideSource(96)


def test_split_side_by_side():
    frame = np.zeros((4, 9, 3), np.uint8)
    frame[:, :4] = 1
    frame[:, 4:8] = 2
    frame[:, 8] = 99  # an odd last column is dropped
    left, right = split_side_by_side(frame)
    assert left.shape == right.shape == (4, 4, 3)
    assert (left == 1).all() and (right == 2).all()
    assert left.flags.c_contiguous and right.flags.c_contiguous
    left, right = split_side_by_side(frame, swap=True)
    assert (left == 2).all() and (right == 1).all()
    with pytest.raises(SourceError):
        split_side_by_side(np.zeros((4, 1, 3), np.uint8))


def test_side_by_side_camera(fake_cams, monkeypatch):
    fake_cams.devices[3] = {"value": 50, "size": (128, 48)}
    src = SideBySideSource(3, size=(128, 48), identity="Stereo cam [046d:0825]")
    f = src.read()
    assert f.left.shape == f.right.shape == (48, 64, 3)
    assert src.name == "Side-by-side camera 3" and f.t_left == f.t_right
    fake_cams.devices[3]["undecodable"] = (2,)
    assert src.read().index == 1 and src.skipped_frames == 1  # the bad one left out
    clock = Clock(monkeypatch)
    cams = listing((3, "Stereo cam"))
    monkeypatch.setattr(cameras, "list_cameras", cams)
    unplug(fake_cams.devices, 3)
    with pytest.raises(SourceUnavailable, match="Reconnecting to side-by-side camera 3.*stopped "
                                                "delivering"):
        src.read()
    fake_cams.devices[3] = {"value": 60, "size": (128, 48)}
    clock.t += cameras.RECONNECT_INTERVAL_S
    f = src.read()
    assert f.left[0, 0, 0] == 61 and src.reconnects == 1 and f.index == 2
    src.close()


def _write_sbs_video(path, n=5, size=(64, 24)):
    w, h = size
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 20.0, (w, h))
    assert writer.isOpened(), "MJPG .avi writing should work in the headless wheel"
    for i in range(n):
        frame = np.zeros((h, w, 3), np.uint8)
        frame[:, : w // 2] = 20 + 40 * i  # left half brightness encodes the frame number
        frame[:, w // 2:] = 230 - 40 * i
        writer.write(frame)
    writer.release()


def test_video_file_source_loops(tmp_path):
    path = tmp_path / "sbs.avi"
    _write_sbs_video(path)
    src = VideoFileSource(path, loop=True, paced=False)
    assert src.nominal_fps == pytest.approx(20.0) and src.name == "Video sbs.avi"
    frames = [src.read() for _ in range(7)]
    assert frames[0].left.shape == (24, 32, 3)
    lefts = [round(float(f.left.mean())) for f in frames]
    rights = [round(float(f.right.mean())) for f in frames]
    assert lefts[:5] == pytest.approx([20, 60, 100, 140, 180], abs=3)
    assert rights[:5] == pytest.approx([230, 190, 150, 110, 70], abs=3)
    assert lefts[5:] == pytest.approx(lefts[:2], abs=1)  # looped to the start
    times = [f.t_left for f in frames]
    assert times == pytest.approx([i / 20.0 for i in range(7)])
    assert [f.index for f in frames] == list(range(7))
    src.close()


def test_video_file_source_end_and_swap(tmp_path):
    path = tmp_path / "sbs.avi"
    _write_sbs_video(path, n=2)
    src = VideoFileSource(path, loop=False, swap=True, paced=False)
    f = src.read()
    assert f.left.mean() > 200 and f.right.mean() < 40
    src.read()
    with pytest.raises(EndOfSource):
        src.read()


def test_video_file_errors(tmp_path):
    with pytest.raises(SourceError, match="does not exist"):
        VideoFileSource(tmp_path / "missing.avi")
    bad = tmp_path / "notes.avi"
    bad.write_text("not a video")
    with pytest.raises(SourceError, match="cannot open video file"):
        VideoFileSource(bad)


def test_video_file_source_paces(tmp_path, monkeypatch):
    path = tmp_path / "sbs.avi"
    _write_sbs_video(path, n=3)
    clock = {"t": 5.0}
    monkeypatch.setattr(cameras.time, "monotonic", lambda: clock["t"])
    monkeypatch.setattr(cameras.time, "sleep", lambda dt: clock.__setitem__("t", clock["t"] + dt))
    src = VideoFileSource(path, paced=True)
    for _ in range(3):
        src.read()
    assert clock["t"] == pytest.approx(5.0 + 2 / 20.0)


class FakeEnumerated:
    """What cv2_enumerate_cameras.enumerate_cameras(backend) returns: CameraInfo objects."""

    def __init__(self, index, name, path, vid, pid, backend):
        self.index, self.name, self.path = index, name, path
        self.vid, self.pid, self.backend = vid, pid, backend


def fake_enumeration(devices):
    """enumerate_cameras(backend) over `devices` {backend: [(index, name, path, vid, pid)]}."""
    def enumerate_fn(backend):
        return [FakeEnumerated(*d, backend) for d in devices.get(backend, [])]

    return enumerate_fn


LINUX = {
    # the library lists every camera under GStreamer and V4L2 (GStreamer first)
    cv2.CAP_GSTREAMER: [(0, "HD Webcam C270", "/dev/video0", 0x046D, 0x0825),
                        (2, "HD Webcam C270", "/dev/video2", 0x046D, 0x0825),
                        (4, "USB2.0 Camera", "/dev/video4", None, None)],
    cv2.CAP_V4L2: [(0, "HD Webcam C270", "/dev/video0", 0x046D, 0x0825),
                   (2, "HD Webcam C270", "/dev/video2", 0x046D, 0x0825),
                   (4, "USB2.0 Camera", "/dev/video4", None, None)],
}


def test_list_cameras_through_the_enumeration_library():
    cams = list_cameras(enumerate_fn=fake_enumeration(LINUX),
                        backends=(cv2.CAP_GSTREAMER, cv2.CAP_V4L2))
    # each camera once, under V4L2 (preferred to GStreamer), with its USB ids
    assert cams == [CameraInfo(0, "HD Webcam C270", "/dev/video0", cv2.CAP_V4L2, 0x046D, 0x0825),
                    CameraInfo(2, "HD Webcam C270", "/dev/video2", cv2.CAP_V4L2, 0x046D, 0x0825),
                    CameraInfo(4, "USB2.0 Camera", "/dev/video4", cv2.CAP_V4L2)]
    assert cams[0].label() == "0: HD Webcam C270 [046d:0825]"
    assert cams[2].label() == "4: USB2.0 Camera"
    windows = {cv2.CAP_MSMF: [(0, "Integrated Webcam", r"\\?\usb#vid_0bda&pid_5520", 0x0BDA,
                               0x5520)],
               cv2.CAP_DSHOW: [(0, "Integrated Webcam", r"\\?\usb#vid_0bda&pid_5520", 0x0BDA,
                                0x5520),
                               (1, "OBS Virtual Camera", None, None, None)]}
    cams = list_cameras(enumerate_fn=fake_enumeration(windows),
                        backends=(cv2.CAP_DSHOW, cv2.CAP_MSMF))
    assert [(c.index, c.name, c.backend) for c in cams] == [
        (0, "Integrated Webcam", cv2.CAP_MSMF), (1, "OBS Virtual Camera", cv2.CAP_DSHOW)]


def test_metadata_nodes_are_left_out_even_when_the_library_cannot_tell(tmp_path, monkeypatch):
    """A webcam's metadata node (/dev/video1, sysfs index 1) looks like a camera to the library
    when it may not open the device; sysfs says which node captures."""
    for n, index in ((0, 0), (1, 1)):
        (tmp_path / f"video{n}").mkdir()
        (tmp_path / f"video{n}" / "index").write_text(f"{index}\n")
    monkeypatch.setattr(cameras, "SYSFS_VIDEO", tmp_path)
    devices = {cv2.CAP_V4L2: [(0, "HD Webcam C270", "/dev/video0", 0x046D, 0x0825),
                              (1, "HD Webcam C270", "/dev/video1", 0x046D, 0x0825)]}
    cams = list_cameras(enumerate_fn=fake_enumeration(devices), backends=(cv2.CAP_V4L2,))
    assert [c.index for c in cams] == [0]


def test_list_cameras_never_raises(monkeypatch, fake_cams):
    assert isinstance(list_cameras(), list)  # whatever this machine has

    def broken(backend):
        raise PermissionError("denied")

    fake_cams.devices = {1: {"value": 0}}
    # the library failing: OpenCV indices are probed instead
    assert [c.index for c in list_cameras(enumerate_fn=broken, backends=(cv2.CAP_V4L2,))] == [1]
    def unopenable(*args):  # probing fails too
        raise RuntimeError("no camera API")

    monkeypatch.setattr(cameras.cv2, "VideoCapture", unopenable)
    assert list_cameras(enumerate_fn=broken, backends=(cv2.CAP_V4L2,)) == []


def test_cameras_open_with_the_backend_the_listing_reports(fake_cams, monkeypatch):
    opened = []

    class Recording(FakeCapture):
        def __init__(self, index, *args):
            opened.append((index, *args))
            super().__init__(index, *args)

    monkeypatch.setattr(cameras.cv2, "VideoCapture", Recording)
    TwoCameraSource(0, 1, backends=(cv2.CAP_V4L2, cv2.CAP_DSHOW)).close()
    TwoCameraSource(0, 1, swap=True, backends=(cv2.CAP_V4L2, cv2.CAP_DSHOW)).close()
    SideBySideSource(0, backend=cv2.CAP_MSMF).close()
    TwoCameraSource(0, 1).close()
    assert opened == [(0, cv2.CAP_V4L2), (1, cv2.CAP_DSHOW), (1, cv2.CAP_DSHOW), (0, cv2.CAP_V4L2),
                      (0, cv2.CAP_MSMF), (0,), (1,)]


def test_a_camera_that_came_back_under_another_index_is_found_again():
    c270 = "HD Webcam C270 [046d:0825]"
    usb = "USB2.0 Camera [1908:2311]"
    now = [CameraInfo(0, "HD Webcam C270", "/dev/video0", 200, 0x046D, 0x0825),
           CameraInfo(6, "USB2.0 Camera", "/dev/video6", 200, 0x1908, 0x2311)]
    # the USB camera was at 2, now at 6; the webcam stayed at 0
    assert cameras.find_cameras_again((0, 2), (c270, usb), now) == (
        (0, 6), ["camera USB2.0 Camera [1908:2311] is now at index 6 (was 2)"])
    # both where they were: nothing moves
    assert cameras.find_cameras_again((0, 6), (c270, usb), now) == ((0, 6), [])
    # two identical webcams (a home-made rig): the one that moved takes the free index
    twins = [CameraInfo(0, "HD Webcam C270", "/dev/video0", 200, 0x046D, 0x0825),
             CameraInfo(4, "HD Webcam C270", "/dev/video4", 200, 0x046D, 0x0825)]
    assert cameras.find_cameras_again((0, 2), (c270, c270), twins)[0] == (0, 4)
    # not plugged in, or nothing remembered: the indices stay (opening then says what is wrong)
    assert cameras.find_cameras_again((0, 2), (c270, "Other"), now)[0] == (0, 2)
    assert cameras.find_cameras_again((0, 2), (), now)[0] == (0, 2)


def test_opening_a_camera_keeps_opencvs_own_warnings_off_the_terminal(capfd):
    """OpenCV prints '[ WARN:0@0.07] ... can't open camera by index' and 'should be configured
    with libavdevice' for a missing camera; our SourceError says it instead."""
    import cv2 as real_cv2

    log = real_cv2.utils.logging
    before = log.getLogLevel()
    log.setLogLevel(log.LOG_LEVEL_WARNING)  # as with --verbose: the opening silences it itself
    try:
        with pytest.raises(SourceError, match="cannot open left camera 57.*choose other cameras"):
            TwoCameraSource(57, 58, size=(64, 48))
        err = capfd.readouterr().err
        assert "WARN" not in err and "libavdevice" not in err
        assert log.getLogLevel() == log.LOG_LEVEL_WARNING  # and puts the level back
    finally:
        log.setLogLevel(before)


def test_probe_lists_openable_indices(fake_cams):
    fake_cams.devices = {1: {"value": 0}, 2: {"value": 0}}
    def broken(backend):
        raise PermissionError("denied")

    cams = list_cameras(max_probe=4, enumerate_fn=broken, backends=(cv2.CAP_V4L2,))
    assert [c.index for c in cams] == [1, 2]
    assert all(("release", i) in fake_cams.log for i in range(4))
