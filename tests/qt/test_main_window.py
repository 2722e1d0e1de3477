"""The main window: tabs, banner, status bar, calibration files, errors, clean shutdown."""

from __future__ import annotations

import gc
import re

import numpy as np
import pytest
from PySide6.QtWidgets import QApplication

from stereo_gui.qt.dialogs.source_dialog import SourceChoice, SourceDialog
from stereo_gui.qt.main_window import TAB_NAMES, MainWindow


def _assert_no_thread_destroyed_warning(qtlog):
    """Let a deleted window's C++ and Python objects go, then check Qt did not warn that a
    QThread was destroyed while still running."""
    QApplication.processEvents()
    gc.collect()
    QApplication.processEvents()
    messages = [r.message for r in qtlog.records]
    assert not any("QThread" in m and "Destroyed" in m for m in messages), messages


def _sim_source(sim_rig):
    from stereo_gui.sources.sim import SimSource

    return SimSource(rig=sim_rig, mode="scene", fps=30)


def test_four_tabs_and_the_simulated_rig_banner(qtbot, ctx, window, sim_rig):
    assert [window.tabs.tabText(i).lower() for i in range(window.tabs.count())] == list(TAB_NAMES)
    assert not window.banner.isVisibleTo(window)
    window.use_source(_sim_source(sim_rig), SourceChoice("auto"), fell_back_to_sim=True,
                      message="no cameras were found")
    assert window.banner.isVisibleTo(window)
    assert "SIMULATED" in window.banner.label.text()
    assert window.source_label.text() == "Source: Simulated rig"
    assert ctx.settings.source == "auto"
    from stereo_gui.qt.tabs.tab import WindowTab

    assert all(isinstance(window.tabs.widget(i), WindowTab) for i in range(window.tabs.count()))
    for name in TAB_NAMES:
        window.show_tab(name)
        assert window.current_tab_name() == name


@pytest.mark.slow
def test_status_bar_shows_frame_rates(qtbot, ctx, window, sim_rig):
    ctx.calibration_model.set(sim_rig.true_calibration(), None,
                              note="simulated rig's TRUE calibration")
    window.show_tab("live")
    window.use_source(_sim_source(sim_rig), SourceChoice("sim"))
    qtbot.waitUntil(lambda: window.live_tab.frames_shown >= 3, timeout=60000)
    qtbot.waitUntil(lambda: "Processing: 0.0" not in window.processing_fps_label.text()
                    and "–" not in window.processing_fps_label.text(), timeout=30000)
    assert window.camera_fps_label.text().endswith("fps")
    assert "TRUE calibration" in window.calibration_label.text()


SHOWN = re.compile(r"^Shown: (\d+\.\d) fps, (\d+) ms, CPU (\d+) %$")


def test_status_bar_shows_the_frames_shown_their_latency_and_the_cpu(qtbot, ctx, window,
                                                                      sim_rig):
    """The third rate: frames drawn in the Live tab per second, their median latency from the
    source's delivery, the process's CPU share; '–' for the rate on another tab, the CPU still."""
    ctx.calibration_model.set(sim_rig.true_calibration(), None,
                              note="simulated rig's TRUE calibration")
    window.show_tab("live")
    window.use_source(_sim_source(sim_rig), SourceChoice("sim"))
    qtbot.waitUntil(lambda: SHOWN.match(window.shown_label.text()) is not None
                    and float(SHOWN.match(window.shown_label.text()).group(1)) > 0,
                    timeout=60000)
    fps, ms, cpu = SHOWN.match(window.shown_label.text()).groups()
    assert int(ms) > 0 and int(cpu) >= 0
    stats = window.live_tab.shown_stats()
    assert stats.latency.count > 0 and stats.latency.p95_ms >= stats.latency.median_ms > 0
    tip = window.shown_label.toolTip()
    assert "95th percentile" in tip and "delivery" in tip and "core" in tip
    window.show_tab("measurements")  # the Live tab draws nothing there
    qtbot.waitUntil(lambda: re.fullmatch(r"Shown: –, CPU \d+ %", window.shown_label.text())
                    is not None, timeout=10000)
    window.show_tab("live")
    window.live_tab.set_paused(True)
    qtbot.waitUntil(lambda: re.fullmatch(r"Shown: paused, CPU \d+ %",
                                         window.shown_label.text()) is not None, timeout=10000)
    window.live_tab.set_paused(False)


def test_open_source_runs_off_the_ui_thread(qtbot, ctx, window):
    with qtbot.waitSignal(window.sourceOpened, timeout=120000) as sig:
        window.open_source(SourceChoice("sim"))
    assert sig.args == ["sim"]
    # chosen, not fallen back to: the banner says SIMULATED all the same
    assert window.banner.isVisibleTo(window) and "chosen" in window.banner.label.text()


def test_a_failing_source_is_reported(qtbot, ctx, window, tmp_path):
    with qtbot.waitSignal(ctx.errorOccurred, timeout=30000) as sig:
        window.open_source(SourceChoice(str(tmp_path / "missing")))
    assert "missing" in sig.args[0]
    assert window.error_bar.isVisibleTo(window)


def test_errors_become_a_visible_message(qtbot, ctx, window):
    ctx.report_error("the left camera was unplugged")
    assert window.error_bar.isVisibleTo(window)
    assert window.error_bar.label.text() == "the left camera was unplugged"
    assert "unplugged" in window.statusBar().currentMessage()


def test_save_and_open_calibration(qtbot, ctx, window, sim_rig, tmp_path):
    assert not window.save_calibration(str(tmp_path / "none.yaml"))  # nothing to save yet
    ctx.calibration_model.set(sim_rig.true_calibration())
    path = tmp_path / "rig.yaml"
    assert window.save_calibration(str(path)) and path.is_file()
    ctx.calibration_model.set(None)
    assert window.calibration_label.text() == "No calibration"
    assert window.open_calibration(str(path))
    assert ctx.calibration is not None and ctx.calibration_path.name == "rig.yaml"
    assert "rig.yaml" in window.calibration_label.text() and "RMS" in window.calibration_label.text()
    assert ctx.settings.last_calibration == str(path.resolve())
    bad = tmp_path / "bad.yaml"
    bad.write_text("%YAML:1.0\nfoo: 1\n")
    assert not window.open_calibration(str(bad))
    assert "bad.yaml" in window.error_bar.label.text()


@pytest.mark.slow
def test_closing_while_live_ends_quickly_without_thread_warnings(qtbot, ctx, sim_rig, qtlog):
    w = MainWindow(ctx)
    w.show()
    ctx.calibration_model.set(sim_rig.true_calibration())
    w.show_tab("live")
    w.use_source(_sim_source(sim_rig), SourceChoice("sim"))
    qtbot.waitUntil(lambda: w.live_tab.frames_shown >= 1, timeout=60000)
    assert ctx.frames.is_running()
    w.close()  # stops and joins every worker (each join is bounded by 2 s)
    assert not ctx.frames.is_running() and not ctx.jobs.is_running()
    w.deleteLater()
    del w
    _assert_no_thread_destroyed_warning(qtlog)


def test_settings_are_saved_on_close(qtbot, ctx, sim_rig):
    from stereo_gui.files.settings import load_settings

    w = MainWindow(ctx)
    qtbot.addWidget(w)
    w.use_source(_sim_source(sim_rig), SourceChoice("sim", (640, 480), True))
    w.close()
    saved, warnings = load_settings()
    assert not warnings
    assert saved.source == "sim" and saved.swap_lr and saved.window_geometry


def test_source_dialog_round_trip(qtbot):
    from stereo_gui.sources.cameras import CameraInfo

    cams = [CameraInfo(0, "HD Webcam", "/dev/video0"), CameraInfo(2, "USB Camera", "/dev/video2")]
    dlg = SourceDialog(SourceChoice("cams:2,0", (320, 240), True), cameras=cams)
    qtbot.addWidget(dlg)
    assert "HD Webcam" in dlg.left_cam.itemText(0)
    assert dlg.choice() == SourceChoice("cams:2,0", (320, 240), True)
    dlg.sbs.setChecked(True)
    assert dlg.choice().spec == "sbs:0"
    dlg.sim.setChecked(True)
    assert dlg.choice().spec == "sim"
    dlg.set_choice(SourceChoice("/data/rec1"))
    assert dlg.choice().spec == "/data/rec1"


@pytest.mark.slow
def test_closing_while_calibrating_ends_without_thread_warnings(qtbot, ctx, tmp_path, qtlog):
    from stereo_gui.sources.sim import write_calibration_set

    (tmp_path / "pairs").mkdir()
    pairs = write_calibration_set(tmp_path / "pairs", n_pairs=6, seed=1)
    w = MainWindow(ctx)
    w.show()
    w.show_tab("calibration")
    w.calibration_tab.folder_edit.setText(str(pairs))
    assert w.calibration_tab.start_calibration()
    worker = w.calibration_tab.worker
    assert worker.isRunning()
    w.close()  # cancels the calibration and joins its thread
    assert not worker.isRunning()
    w.deleteLater()
    del w
    _assert_no_thread_destroyed_warning(qtlog)


def test_export_and_import_ros_camera_info(qtbot, ctx, window, sim_rig, tmp_path):
    import numpy as np
    import yaml

    errors = []
    ctx.errorOccurred.connect(errors.append)
    assert window.export_ros(str(tmp_path)) is None and "no calibration" in errors[-1]
    calib = sim_rig.true_calibration()
    ctx.calibration_model.set(calib)
    left, right = window.export_ros(str(tmp_path))
    assert (left.name, right.name) == ("left.yaml", "right.yaml")
    doc = yaml.safe_load(right.read_text())
    assert (doc["image_width"], doc["image_height"]) == calib.image_size
    P2 = np.array(doc["projection_matrix"]["data"]).reshape(3, 4)
    assert P2[0, 3] == pytest.approx(calib.P2[0, 3] / 1000.0)  # ROS: metres
    assert "left.yaml" in window.statusBar().currentMessage()

    ctx.calibration_model.set(None)
    assert window.import_ros(str(left), str(right))
    back = ctx.calibration
    assert back is not None and back.image_size == calib.image_size
    np.testing.assert_allclose(back.M1, calib.M1)
    np.testing.assert_allclose(back.P2, calib.P2, atol=1e-9)
    assert back.rectified_baseline_mm == pytest.approx(calib.rectified_baseline_mm)
    assert "ROS left.yaml + right.yaml" in window.calibration_label.text()
    assert not window.import_ros(str(right), str(tmp_path / "none.yaml"))
    assert "none.yaml" in errors[-1]


def test_ros_files_are_told_apart_by_name():
    from stereo_gui.qt.models.calibration import order_left_right

    assert order_left_right(["/a/cam_right.yaml", "/a/cam_left.yaml"]) == \
        ("/a/cam_left.yaml", "/a/cam_right.yaml")
    assert order_left_right(["/a/b.yaml", "/a/a.yaml"]) == ("/a/a.yaml", "/a/b.yaml")


def test_help_about_opens_the_about_dialog(window, qtbot):
    from stereo_gui.qt.dialogs.about import AboutDialog

    window.show_about()
    qtbot.waitUntil(lambda: any(isinstance(w, AboutDialog) and w.isVisible()
                                for w in window.findChildren(AboutDialog)), timeout=30000)
    dialog = window.findChildren(AboutDialog)[0]
    dialog.close()


def test_a_chosen_simulated_rig_has_the_banner_too(qtbot, ctx, window, sim_rig, array_source):
    """`--source sim` (or the rig chosen in the dialog) says SIMULATED as loudly as the
    automatic fallback does; a real source takes the banner away."""
    window.use_source(_sim_source(sim_rig), SourceChoice("sim"))
    assert window.banner.isVisibleTo(window) and "SIMULATED" in window.banner.label.text()
    assert "chosen" in window.banner.label.text()
    window.use_source(array_source(), SourceChoice("cams:0,1"))
    assert not window.banner.isVisibleTo(window)


def test_the_window_fits_laptop_screens(qtbot, ctx, window, sim_rig):
    """Usable at 1366x768 and 1280x720, reachable at 1024x768: no tab needs more room than a
    1024x768 screen has, a new window starts within the screen and the Live toolbar wraps
    instead of cutting buttons off."""
    from PySide6.QtCore import QRect

    from stereo_gui.qt.main_window import default_window_size

    assert default_window_size(QRect(0, 0, 1280, 720)) == (1280, 720 - 32)
    assert default_window_size(QRect(0, 0, 1366, 768)) == (1366, 768 - 32)
    assert default_window_size(QRect(0, 0, 1920, 1080)) == (1366, 860)
    for name in TAB_NAMES:
        window.show_tab(name)
        hint = window.minimumSizeHint()
        assert hint.width() <= 1024 and hint.height() <= 768 - 32, (name, hint)
    ctx.calibration_model.set(sim_rig.true_calibration())  # the Live tab shows its views
    window.show_tab("live")
    live = window.live_tab
    window.banner.show_text("SIMULATED " * 40)  # a banner of two lines takes its room too
    for width in (1280, 1024):
        window.resize(width, 200)  # as short as the window can be: its minimum height
        qtbot.waitUntil(lambda w=width: window.width() == w, timeout=5000)
        QApplication.processEvents()
        page = live.toolbar
        for b in (live.ruler_button, live.pause_button, live.export_button, live.record_button,
                  live.params_button, live.cloud_button, live.region_button):
            assert page.rect().contains(b.geometry()), (width, b.text(), b.geometry())
        # the wrapped rows get their height: nothing below the toolbar is drawn over
        below = live.views.geometry().top()
        assert page.geometry().bottom() < below, (width, page.geometry(), below)
    # the parameters give their room to the views
    live.params_button.setChecked(False)
    assert not live.params_scroll.isVisibleTo(live)
    live.params_button.setChecked(True)
    assert live.params_scroll.isVisibleTo(live)


def test_open_recent_lists_calibrations_sessions_and_recordings(qtbot, ctx, window, sim_rig,
                                                               tmp_path):
    from stereo_gui.files.calibration_file import save_calibration
    from stereo_gui.files.recording import RecordingWriter
    from stereo_gui.files.session import MANIFEST
    from stereo_gui.qt.main_window import recent_entry
    from stereo_gui.sources.base import StereoFrame

    calib = tmp_path / "rig.yaml"
    save_calibration(sim_rig.true_calibration(), calib)
    assert window.open_calibration(str(calib))
    rng = np.random.default_rng(1)
    with RecordingWriter(tmp_path / "rec", fps=10, background=False) as w:
        for k in range(3):
            img = rng.integers(0, 255, (24, 32, 3), dtype=np.uint8)
            w.write(StereoFrame(img, img, 0.1 * k, 0.1 * k, k))
    with qtbot.waitSignal(window.sourceOpened, timeout=60000):
        window.open_source(SourceChoice(str(tmp_path / "rec")))
    session = tmp_path / "session"
    session.mkdir()
    (session / MANIFEST).write_text("{}")
    ctx.settings_model.update(last_session=str(session))  # what the Capture tab does
    recent = ctx.settings.recent_files
    assert recent[:3] == (str(session), str(tmp_path / "rec"), str(calib))
    assert [recent_entry(p)[0] for p in recent[:3]] == ["session", "recording", "calibration"]
    window.recent_menu.aboutToShow.emit()  # as when File > Open recent opens
    texts = [a.text() for a in window.recent_menu.actions()]
    assert texts[0].startswith("Session: session") and texts[2].startswith("Calibration: rig")
    ctx.calibration_model.set(None)
    assert window.open_recent(str(calib)) and ctx.calibration is not None
    assert recent_entry(str(tmp_path / "gone.yaml"))[0] == "missing"
    assert not window.open_recent(str(tmp_path / "gone.yaml"))


def test_shortcuts_switch_tabs_and_space_pauses_live_only(qtbot, ctx, window):
    from PySide6.QtGui import QKeySequence

    from stereo_gui.qt.main_window import SOURCE_SHORTCUT

    assert window.act_source.shortcut() == QKeySequence(SOURCE_SHORTCUT)
    for i, name in enumerate(TAB_NAMES):
        assert window.tab_shortcuts[i].key() == QKeySequence(f"Ctrl+{i + 1}")
        window.tab_shortcuts[i].activated.emit()
        assert window.current_tab_name() == name
        assert window.pause_shortcut.isEnabled() == (name == "live")
    window.show_tab("live")
    window.pause_shortcut.activated.emit()
    assert window.live_tab.pause_button.isChecked() and ctx.frames.paused
    window.pause_shortcut.activated.emit()
    assert not window.live_tab.pause_button.isChecked() and not ctx.frames.paused


def test_export_kalibr_camchain_and_open_it_again(qtbot, ctx, window, sim_rig, tmp_path):
    import dataclasses

    import numpy as np

    errors = []
    ctx.errorOccurred.connect(errors.append)
    assert window.export_kalibr(str(tmp_path / "c.yaml")) is None and "no calibration" in errors[-1]
    ctx.calibration_model.set(sim_rig.true_calibration())  # k3 != 0: Kalibr has no such model
    assert window.export_kalibr(str(tmp_path / "c.yaml")) is None
    assert "k3" in errors[-1] and not (tmp_path / "c.yaml").exists()
    calib = sim_rig.true_calibration()
    D1, D2 = calib.D1.copy(), calib.D2.copy()
    D1.reshape(-1)[4] = D2.reshape(-1)[4] = 0.0
    calib = dataclasses.replace(calib, D1=D1, D2=D2)
    ctx.calibration_model.set(calib)
    path = window.export_kalibr(str(tmp_path / "camchain.yaml"))
    assert path == tmp_path / "camchain.yaml" and "Kalibr" in window.statusBar().currentMessage()
    assert window.open_calibration(str(path))
    np.testing.assert_allclose(ctx.calibration.M1, calib.M1)
    np.testing.assert_allclose(ctx.calibration.T, calib.T, rtol=1e-9)
