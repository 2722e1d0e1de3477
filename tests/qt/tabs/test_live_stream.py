"""The Live tab's Stream switch and File menu's MCAP recording: the window serves the same depth
as `stereo-gui serve`, remembers the switch, and says where and to how many clients."""

from __future__ import annotations

import pytest

pytest.importorskip("foxglove")

from stereo_gui.files.mcap_file import read_topics
from stereo_gui.pipeline.stream import TOPICS, DepthStream
from stereo_gui.qt.tabs.live import MCAP_STOP_TEXT, MCAP_TEXT, TRUE_CALIBRATION_NOTE
from tests.qt.tabs.test_live_tab import double_click


def _wall(qtbot, ctx, live, sim_rig, wall_pair, array_source):
    _scene, left, right = wall_pair
    ctx.calibration_model.set(sim_rig.true_calibration(), None, note=TRUE_CALIBRATION_NOTE)
    ctx.frames.set_source(array_source(left, right, fps=30))
    with qtbot.waitSignal(live.frameShown, timeout=30000):
        pass


def test_stream_serves_frames_and_is_remembered(qtbot, ctx, live, sim_rig, wall_pair,
                                                array_source):
    ctx.settings_model.update(stream_port=0)  # any free port (the default is 8765)
    _wall(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    assert not live.stream.label.isVisibleTo(live)
    live.stream_button.click()
    assert live.stream.serving and ctx.settings.stream_on
    qtbot.waitUntil(lambda: live.stream.stats().frames >= 3, timeout=30000)
    qtbot.waitUntil(lambda: "frames/s" in live.stream.label.text()
                    and "no frames" not in live.stream.label.text(), timeout=5000)
    text = live.stream.label.text()
    assert text.startswith("Streaming on ws://127.0.0.1:") and "0 clients" in text
    assert live.stream.label.isVisibleTo(live)
    live.stream_button.click()  # off
    assert not live.stream.serving and not ctx.settings.stream_on
    assert not live.stream.label.isVisibleTo(live)


def test_a_taken_port_is_said_and_the_switch_goes_back(qtbot, ctx, live):
    errors = []
    ctx.errorOccurred.connect(errors.append)
    with DepthStream() as other:
        port = int(other.serve(port=0).rsplit(":", 1)[1])
        ctx.settings_model.update(stream_port=port)
        live.stream_button.click()
    assert not live.stream_button.isChecked() and not ctx.settings.stream_on
    assert errors and "in use" in errors[-1]


def test_the_file_menu_records_mcap_with_the_readings(qtbot, ctx, window, sim_rig, wall_pair,
                                                      array_source, tmp_path):
    live = window.live_tab
    _wall(qtbot, ctx, live, sim_rig, wall_pair, array_source)
    path = tmp_path / "depth.mcap"
    assert window.toggle_mcap(str(path)) == path
    assert window.act_mcap.text().startswith("Stop")
    assert live.mcap_action.text() == MCAP_STOP_TEXT  # the Record button's menu says so too
    assert not window.act_stream.isChecked()  # recording does not serve
    qtbot.waitUntil(lambda: live.stream.stats().frames >= 2, timeout=30000)
    panel = live.panels["wls"]
    pos = panel.widget_pos_of_pixel(400.0, 240.0)
    with qtbot.waitSignal(live.measured, timeout=30000):
        double_click(qtbot, panel.viewport(), pos)
    window.toggle_mcap()  # stop
    assert window.act_mcap.text().startswith("Record") and live.mcap_action.text() == MCAP_TEXT
    counts = read_topics(path)
    assert counts[TOPICS["depth"]] >= 2 and counts[TOPICS["readings"]] == 1
    assert live.stream.stats() is None  # neither serving nor recording: nothing kept open


def test_the_menu_switch_and_the_button_are_one(qtbot, ctx, window):
    ctx.settings_model.update(stream_port=0)
    window.act_stream.trigger()
    assert window.live_tab.stream_button.isChecked() and window.live_tab.stream.serving
    window.live_tab.stream_button.click()
    assert not window.act_stream.isChecked() and not window.live_tab.stream.serving


def test_a_stream_left_on_is_on_again_after_a_restart(qtbot, sim_rig, tmp_path):
    from stereo_gui.files.calibration_file import save_calibration
    from stereo_gui.files.settings import Settings, save_settings
    from stereo_gui.qt.app import build_window

    calib = tmp_path / "rig.yaml"
    save_calibration(sim_rig.true_calibration(), calib)
    save_settings(Settings(source="sim", last_calibration=str(calib), stream_on=True,
                           stream_port=0))
    _ctx, window = build_window()
    qtbot.addWidget(window)
    try:
        assert window.live_tab.stream.serving and window.act_stream.isChecked()
    finally:
        window.close()
    assert not window.live_tab.stream.serving  # closing the window stops serving
