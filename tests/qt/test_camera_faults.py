"""The window over camera faults, with fake captures (tests/fake_cameras.py): a bad frame is
skipped and counted in the status bar, a vanished camera is reconnected by itself and says so,
the rate falls to 0 meanwhile, and the error bar about it goes when frames come again."""

from __future__ import annotations

import pytest
from fake_cameras import FakeCapture, unplug

import stereo_gui.qt.workers.frame_status as frame_status
import stereo_gui.sources.cameras as cameras
from stereo_gui.qt.dialogs.source_dialog import SourceChoice
from stereo_gui.sources.cameras import CameraInfo, TwoCameraSource

IDENT = ("Fake cam L [1234:0001]", "Fake cam R [1234:0002]")


@pytest.fixture
def fake_cams(monkeypatch):
    period = 1 / 50  # the fake cameras' frame clock, s
    FakeCapture.devices = {0: {"value": 10, "period_s": period},
                           1: {"value": 100, "period_s": period}}
    FakeCapture.log = []
    monkeypatch.setattr(cameras.cv2, "VideoCapture", FakeCapture)

    def listed():
        return [CameraInfo(i, IDENT[i].split(" [")[0], f"/dev/video{i}", None, 0x1234, i + 1)
                for i in sorted(FakeCapture.devices) if i in (0, 1)]

    monkeypatch.setattr(cameras, "list_cameras", listed)
    monkeypatch.setattr(frame_status, "RATE_STALE_S", 0.3)  # the test need not wait 2 s
    return FakeCapture


def test_a_bad_frame_and_a_vanished_camera_in_the_window(qtbot, ctx, window, fake_cams):
    src = TwoCameraSource(0, 1, size=(64, 48), identities=IDENT)
    src.reconnect_interval_s = 0.2
    fake_cams.devices[1]["undecodable"] = (3,)
    window.use_source(src, SourceChoice("cams:0,1", (64, 48), False), cameras=IDENT)
    qtbot.waitUntil(lambda: ctx.frames.status().frames_read > 5, timeout=30000)
    # the status bar's timer updates the rates twice a second
    qtbot.waitUntil(lambda: window.camera_fps_label.text().endswith("fps, 1 bad frame skipped"),
                    timeout=10000)
    assert window.source_label.text() == "Source: Cameras 0, 1"
    assert not window.error_bar.isVisible()

    unplug(fake_cams.devices, 1)
    qtbot.waitUntil(lambda: ctx.frames.status().stream == "reconnecting", timeout=30000)
    qtbot.waitUntil(lambda: window.error_bar.isVisible(), timeout=30000)
    assert "Reconnecting to right camera 1 (Fake cam R [1234:0002])" in \
        window.error_bar.label.text()
    assert window.source_label.text() == "Source: Cameras 0, 1 (reconnecting…)"
    # no frame arrives: the rate shown falls to 0 instead of keeping the last one
    qtbot.waitUntil(lambda: ctx.frames.status().camera_fps == 0.0, timeout=30000)
    qtbot.waitUntil(lambda: window.camera_fps_label.text().startswith("Camera: 0.0 fps"),
                    timeout=10000)

    n = ctx.frames.status().frames_read
    fake_cams.devices[1] = {"value": 200, "period_s": 1 / 50}  # plugged in again
    qtbot.waitUntil(lambda: ctx.frames.status().frames_read > n + 3, timeout=30000)
    qtbot.waitUntil(lambda: not window.error_bar.isVisible(), timeout=30000)
    assert window.source_label.text() == "Source: Cameras 0, 1"
    assert window.statusBar().currentMessage() == "Cameras 0, 1: frames again"
    assert src.reconnects == 1 and ctx.frames.source() is src
    frame = ctx.frames.latest().frame
    assert frame.right.shape == (48, 64, 3) and frame.right[0, 0, 0] > 200


def test_a_newer_error_stays_when_the_stream_recovers(qtbot, ctx, window, fake_cams):
    src = TwoCameraSource(0, 1, size=(64, 48), identities=IDENT)
    src.reconnect_interval_s = 0.2
    window.use_source(src, SourceChoice("cams:0,1", (64, 48), False), cameras=IDENT)
    qtbot.waitUntil(lambda: ctx.frames.status().frames_read > 2, timeout=30000)
    unplug(fake_cams.devices, 0)
    qtbot.waitUntil(lambda: window.error_bar.isVisible(), timeout=30000)
    ctx.report_error("Cannot save calibration x.yaml: permission denied")
    ok = frame_status.StreamState.OK
    with qtbot.waitSignal(ctx.frames.streamStatus, timeout=30000,
                          check_params_cb=lambda status: status.state is ok):
        fake_cams.devices[0] = {"value": 10, "period_s": 1 / 50}
    assert window.error_bar.isVisible()
    assert "permission denied" in window.error_bar.label.text()


def test_a_source_that_stops_leaves_the_status_bar(qtbot, ctx, window, fake_cams):
    src = TwoCameraSource(0, 1, size=(64, 48), identities=IDENT)
    window.use_source(src, SourceChoice("cams:0,1", (64, 48), False), cameras=IDENT)
    qtbot.waitUntil(lambda: ctx.frames.status().frames_read > 2, timeout=30000)
    fake_cams.devices[1]["size"] = (32, 24)  # a frame the other camera's size does not match
    qtbot.waitUntil(lambda: ctx.frames.status().stream == "failed", timeout=30000)
    qtbot.waitUntil(lambda: window.source_label.text() == "Source: none (Cameras 0, 1 stopped)",
                    timeout=30000)
    assert "different image sizes" in window.error_bar.label.text()
