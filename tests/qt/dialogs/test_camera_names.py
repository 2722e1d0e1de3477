"""Camera names in the source dialog come from cv2-enumerate-cameras (here a fake enumeration),
and a remembered camera that came back under another index is found again."""

from __future__ import annotations

import cv2
import pytest
from fake_cameras import PresentCapture

import stereo_gui.sources.cameras as cameras


class _Listed:
    def __init__(self, index, name, path, vid, pid, backend):
        self.index, self.name, self.path, self.vid, self.pid = index, name, path, vid, pid
        self.backend = backend


@pytest.fixture
def fake_library(monkeypatch):
    """cv2_enumerate_cameras listing two webcams under V4L2 (the USB camera at index `usb`)."""
    import cv2_enumerate_cameras

    state = {"usb": 2}

    def enumerate_cameras(backend):
        if backend != cv2.CAP_V4L2:
            return []
        return [_Listed(0, "HD Webcam C270", "/dev/video0", 0x046D, 0x0825, backend),
                _Listed(state["usb"], "USB2.0 Camera", f"/dev/video{state['usb']}", 0x1908,
                        0x2311, backend)]

    monkeypatch.setattr(cv2_enumerate_cameras, "enumerate_cameras", enumerate_cameras)
    monkeypatch.setattr(cv2_enumerate_cameras, "supported_backends",
                        (cv2.CAP_GSTREAMER, cv2.CAP_V4L2))
    return state


_Cap = PresentCapture


def test_source_dialog_shows_names_and_usb_ids(qtbot, fake_library):
    from stereo_gui.qt.dialogs.source_dialog import SourceChoice, SourceDialog

    dlg = SourceDialog(SourceChoice("cams:0,2"))
    qtbot.addWidget(dlg)
    items = [dlg.left_cam.itemText(i) for i in range(dlg.left_cam.count())]
    assert items == ["0: HD Webcam C270 [046d:0825]", "2: USB2.0 Camera [1908:2311]"]
    assert dlg.choice().spec == "cams:0,2"


def test_a_replugged_camera_is_found_under_its_new_index(qtbot, ctx, window, fake_library,
                                                          monkeypatch):
    from stereo_gui.qt.dialogs.source_dialog import SourceChoice

    monkeypatch.setattr(cameras.cv2, "VideoCapture", _Cap)
    _Cap.present, _Cap.backends = {0, 2}, []
    with qtbot.waitSignal(window.sourceOpened, timeout=10000):
        window.open_source(SourceChoice("cams:0,2", (64, 48)))
    assert ctx.settings.source == "cams:0,2"
    assert ctx.settings.cameras == ("HD Webcam C270 [046d:0825]", "USB2.0 Camera [1908:2311]")
    assert _Cap.backends == [(0, cv2.CAP_V4L2), (2, cv2.CAP_V4L2)]  # the backend listed
    # unplugged and plugged in again: the USB camera is now /dev/video5
    fake_library["usb"] = 5
    _Cap.present = {0, 5}
    with qtbot.waitSignal(window.sourceOpened, timeout=10000) as opened:
        window.open_source(SourceChoice("cams:0,2", (64, 48)))
    assert opened.args == ["cams:0,5"] and ctx.settings.source == "cams:0,5"
    window.ctx.frames.set_source(None)
