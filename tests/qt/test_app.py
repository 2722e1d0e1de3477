"""The application shell: start and auto-quit, start-up arguments."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from stereo_gui.qt.source_capabilities import simulated_rig


def _env(tmp_path, **extra):
    env = dict(os.environ)
    env.update({"QT_QPA_PLATFORM": "offscreen", "STEREO_GUI_CONFIG_DIR": str(tmp_path / "cfg")})
    env.update(extra)
    return env


@pytest.mark.slow
def test_app_starts_and_quits_by_itself(tmp_path):
    """`STEREO_GUI_QUIT_AFTER` closes the window; exit 0, no traceback, settings saved.

    6 s: the source is remembered once it has opened, and building the simulated rig takes
    a few seconds on a busy machine."""
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "--source", "sim"],
                          env=_env(tmp_path, STEREO_GUI_QUIT_AFTER="6"), capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr and "QThread: Destroyed" not in proc.stderr
    assert (tmp_path / "cfg" / "settings.json").is_file()
    assert '"source": "sim"' in (tmp_path / "cfg" / "settings.json").read_text()


@pytest.mark.slow
def test_bad_command_line_source_exits_2_with_one_line(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "--source", str(tmp_path / "nope")],
                          env=_env(tmp_path, STEREO_GUI_QUIT_AFTER="0"), capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "nope" in lines[0] and "Traceback" not in proc.stderr


def test_bad_quit_after_value_is_refused(monkeypatch):
    from stereo_gui.core.errors import InputError
    from stereo_gui.qt.app import quit_after_seconds

    monkeypatch.setenv("STEREO_GUI_QUIT_AFTER", "soon")
    with pytest.raises(InputError, match="STEREO_GUI_QUIT_AFTER"):
        quit_after_seconds()
    monkeypatch.setenv("STEREO_GUI_QUIT_AFTER", "1.5")
    assert quit_after_seconds() == 1.5
    for raw in ("inf", "1e10", "nan", "-1"):  # the probe: an abort (1e10) or OverflowError (inf)
        monkeypatch.setenv("STEREO_GUI_QUIT_AFTER", raw)
        with pytest.raises(InputError, match="from 0 to 86400 seconds"):
            quit_after_seconds()


def test_quit_after_inf_exits_2_with_one_line(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "--source", "sim"],
                          env=_env(tmp_path, STEREO_GUI_QUIT_AFTER="inf"), capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "STEREO_GUI_QUIT_AFTER" in lines[0], proc.stderr


@pytest.mark.slow
def test_build_window_loads_the_last_calibration_and_reports_a_broken_one(qtbot, sim_rig, tmp_path):
    from stereo_gui.files.calibration_file import save_calibration
    from stereo_gui.files.settings import Settings, save_settings
    from stereo_gui.qt.app import build_window

    good = tmp_path / "rig.yaml"
    save_calibration(sim_rig.true_calibration(), good)
    save_settings(Settings(source="sim", last_calibration=str(good)))
    ctx, window = build_window()
    qtbot.addWidget(window)
    try:
        assert ctx.calibration is not None and ctx.calibration_path == good.resolve()
        assert "rig.yaml" in window.calibration_label.text()
    finally:
        window.close()
    broken = tmp_path / "broken.yaml"
    broken.write_text("not a calibration")
    save_settings(Settings(source="sim", last_calibration=str(broken)))
    ctx, window = build_window()
    qtbot.addWidget(window)
    try:
        assert ctx.calibration is None
        assert window.error_bar.isVisibleTo(window)
        assert "broken.yaml" in window.error_bar.label.text()
    finally:
        window.close()


@pytest.mark.slow
def test_the_simulated_rigs_true_calibration_is_chosen_again_after_a_restart(
        qtbot, sim_rig, tmp_path):
    """Choosing the simulated rig's true calibration survives quitting and starting again (on
    the rig; the file remembered before stays for other sources), and loading a file afterwards
    ends it."""
    from stereo_gui.files.calibration_file import save_calibration
    from stereo_gui.files.settings import Settings, load_settings, save_settings
    from stereo_gui.qt.context import TRUE_CALIBRATION_NOTE

    good = tmp_path / "rig.yaml"
    save_calibration(sim_rig.true_calibration(), good)
    save_settings(Settings(source="sim", last_calibration=str(good)))
    ctx, window = _start(qtbot)
    try:
        qtbot.waitUntil(lambda: simulated_rig(ctx.frames.source()) is not None, timeout=60000)
        # frames are shown, and the calibration chosen at the start is still the one in use
        qtbot.waitUntil(lambda: window.live_tab.frames_shown > 0, timeout=60000)
        assert ctx.calibration_path == good.resolve()  # nothing chosen yet: the file
        assert window.live_tab.use_true_calibration()
    finally:
        window.close()
    saved = load_settings()[0]
    assert saved.sim_true_calibration and saved.last_calibration == str(good.resolve())

    ctx, window = _start(qtbot)
    try:
        qtbot.waitUntil(lambda: ctx.calibration_note == TRUE_CALIBRATION_NOTE, timeout=60000)
        assert ctx.calibration_path is None and window.live_tab.calib_note.isVisibleTo(window)
        assert ctx.calibration_model.open_file(good)  # another choice ends it
        assert not ctx.settings.sim_true_calibration
    finally:
        window.close()

    ctx, window = _start(qtbot)
    try:
        qtbot.waitUntil(lambda: simulated_rig(ctx.frames.source()) is not None, timeout=60000)
        # frames are shown, and the calibration chosen at the start is still the one in use
        qtbot.waitUntil(lambda: window.live_tab.frames_shown > 0, timeout=60000)
        assert ctx.calibration_path == good.resolve() and ctx.calibration_note == ""
    finally:
        window.close()


# ---- remembered files that are bad never block the start -----------------------------------
def _bad_header_calibration(sim_rig, path):
    """A calibration whose M1 header says 4 rows but holds 9 numbers."""
    from stereo_gui.files.calibration_file import save_calibration

    save_calibration(sim_rig.true_calibration(), path)
    text = path.read_text()
    start = text.index("M1: !!opencv-matrix")
    text = text[:start] + text[start:].replace("rows: 3", "rows: 4", 1)
    path.write_text(text)
    return path


def _nan_scale_calibration(sim_rig, path):
    from stereo_gui.files.calibration_file import save_calibration

    save_calibration(sim_rig.true_calibration(), path)
    path.write_text(path.read_text() + "scaled_from_width: .nan\nscaled_from_height: 480\n")
    return path


def _write_settings(doc):
    import json

    from stereo_gui.files.settings import settings_path

    settings_path().parent.mkdir(parents=True, exist_ok=True)
    settings_path().write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return settings_path()


def _start(qtbot):
    from stereo_gui.qt.app import build_window

    ctx, window = build_window()
    qtbot.addWidget(window)
    return ctx, window


def test_bad_remembered_files_are_reported_and_defaults_used(qtbot, sim_rig, tmp_path):
    session = tmp_path / "session"
    session.mkdir()
    (session / "session.json").write_text("[1, 2, 3]")
    _write_settings({"format_version": 1, "source": "sim", "window_geometry": "AdnQywADé€",
                     "last_calibration": str(_bad_header_calibration(sim_rig, tmp_path / "c.yaml")),
                     "last_session": str(session)})
    ctx, window = _start(qtbot)
    try:
        text = " ".join(window.error_bar.messages())
        assert window.error_bar.isVisibleTo(window)
        assert "window_geometry" in text  # the geometry is not used
        assert "c.yaml" in text and "M1" in text  # the calibration is not loaded
        assert ctx.calibration is None
        assert "session.json" in text  # the session opened without its manifest
    finally:
        window.close()


def test_a_nan_scale_in_the_last_calibration_is_reported(qtbot, sim_rig, tmp_path):
    path = _nan_scale_calibration(sim_rig, tmp_path / "nan.yaml")
    _write_settings({"format_version": 1, "source": "sim", "last_calibration": str(path)})
    ctx, window = _start(qtbot)
    try:
        assert ctx.calibration is None
        assert "scaled_from_width" in window.error_bar.label.text()
    finally:
        window.close()


def test_deeply_nested_settings_give_the_defaults(qtbot):
    _write_settings("[" * 100_000 + "]" * 100_000)
    ctx, window = _start(qtbot)
    try:
        assert "nested too deeply" in window.error_bar.label.text()
        assert ctx.settings.preset == "live"
    finally:
        window.close()


def test_a_newer_versions_settings_file_is_left_on_disk(qtbot):
    path = _write_settings({"format_version": 99, "source": "sim", "preset": "future"})
    before = path.read_bytes()
    ctx, window = _start(qtbot)
    try:
        assert "newer version" in window.error_bar.label.text()
    finally:
        window.close()  # saves the settings: it must not replace the newer file
    assert path.read_bytes() == before


@pytest.mark.slow
def test_the_application_starts_with_bad_remembered_files(tmp_path, sim_rig):
    """A remembered session that is no session, a calibration with a bad header and a window
    geometry that is no base64: the window starts, no traceback, exit status 0."""
    import json

    session = tmp_path / "session"
    session.mkdir()
    (session / "session.json").write_text("[1, 2, 3]")
    cfg = tmp_path / "cfg"
    cfg.mkdir()
    (cfg / "settings.json").write_text(json.dumps(
        {"format_version": 1, "source": "sim", "window_geometry": "AdnQywADé€",
         "last_calibration": str(_bad_header_calibration(sim_rig, tmp_path / "c.yaml")),
         "last_session": str(session)}))
    proc = subprocess.run([sys.executable, "-m", "stereo_gui"],
                          env=_env(tmp_path, STEREO_GUI_QUIT_AFTER="1"), capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr


LOGS = {  # the probe's measurement logs that stopped the start (exit 1 or an abort)
    "100k deep": "[" * 100_000 + "]" * 100_000,
    "5000 digits": '{"format_version": 1, "records": [], "n": ' + "9" * 5000 + "}",
    "10^400": '{"format_version": 1, "records": [{"time": "t", "x_px": 1' + "0" * 400 + "}]}",
}


@pytest.mark.parametrize("kind", sorted(LOGS))
def test_a_log_that_cannot_be_read_is_set_aside_said_and_the_start_goes_on(qtbot, kind):
    from stereo_gui.files.measurement_log import default_log_path

    log = default_log_path()
    log.parent.mkdir(parents=True, exist_ok=True)
    log.write_text(LOGS[kind])
    _write_settings({"format_version": 1, "source": "sim"})
    ctx, window = _start(qtbot)
    try:
        assert ctx.measurement_log.records == ()
        said = [m for m in window.error_bar.messages() if "measurement log" in m]
        assert len(said) == 1 and "measurement-log.json.unreadable" in said[0]
        assert log.with_name(log.name + ".unreadable").read_text() == LOGS[kind]
    finally:
        window.close()


@pytest.mark.slow
def test_the_application_starts_with_a_log_100k_deep(tmp_path):
    """A measurement log nested 100,000 levels deep is set aside and the window starts (no
    RecursionError, exit 0)."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "measurement-log.json").write_text(LOGS["100k deep"])
    proc = subprocess.run([sys.executable, "-m", "stereo_gui", "--source", "sim"],
                          env=_env(tmp_path, STEREO_GUI_QUIT_AFTER="1",
                                   STEREO_GUI_DATA_DIR=str(data)),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert (data / "measurement-log.json.unreadable").is_file()


def test_every_problem_of_a_start_is_kept_in_the_error_bar(qtbot, tmp_path):
    """Each of several problems at start is kept in the error bar (the source's failure, which
    comes last, does not replace the others); the bar shows the newest and opens the list of
    all."""
    from stereo_gui.files.measurement_log import default_log_path
    from stereo_gui.files.presets import user_preset_dir

    log = default_log_path()
    log.parent.mkdir(parents=True, exist_ok=True)
    log.write_text("{not json")
    bad_calib = tmp_path / "bad.yaml"
    bad_calib.write_text("not a calibration")
    user_preset_dir().mkdir(parents=True)
    (user_preset_dir() / "mine.json").write_text("{broken")
    not_a_folder = tmp_path / "recordings"
    not_a_folder.write_text("a file")
    _write_settings({"format_version": 1, "source": str(tmp_path / "missing-recording"),
                     "last_calibration": str(bad_calib), "window_geometry": "AdnQé€",
                     "preset": "mine", "recordings_dir": str(not_a_folder)})
    ctx, window = _start(qtbot)
    bar = window.error_bar
    try:
        qtbot.waitUntil(lambda: any("Cannot open the source" in m for m in bar.messages()),
                        timeout=60000)
        text = "\n".join(bar.messages())
        for words in ("window_geometry", "measurement log", "bad.yaml", "preset 'mine'",
                      "recordings folder", "missing-recording"):
            assert words in text, words
        assert bar.label.text() == bar.messages()[-1]
        assert bar.all_button.isVisibleTo(window) and "All" in bar.all_button.text()
        bar.all_button.click()  # the list the person opens
        assert bar.list.isVisibleTo(window) and bar.list.count() == len(bar.messages())
        assert ctx.settings.preset == "mine"  # nothing forgotten that the person chose
    finally:
        window.close()


def test_a_recording_not_closed_cleanly_is_said_in_the_window(qtbot, tmp_path):
    import numpy as np

    from stereo_gui.files.recording import RecordingWriter
    from stereo_gui.sources.base import StereoFrame

    rec = tmp_path / "rec"
    w = RecordingWriter(rec, fps=30.0, background=False)
    for i in range(3):
        img = np.full((48, 64, 3), 40 * i, np.uint8)
        w.write(StereoFrame(img, img, i / 30, i / 30, i))
    # not closed: as after a crash (the frames written are kept)
    _write_settings({"format_version": 1, "source": str(rec), "resolution": [64, 48]})
    ctx, window = _start(qtbot)
    try:
        qtbot.waitUntil(lambda: any("not closed cleanly" in m
                                    for m in window.error_bar.messages()), timeout=60000)
    finally:
        window.close()


def test_a_settings_folder_that_is_a_file_is_said_in_the_window(qtbot, monkeypatch, tmp_path):
    cfg = tmp_path / "cfg"
    cfg.write_text("a file")
    monkeypatch.setenv("STEREO_GUI_CONFIG_DIR", str(cfg))
    ctx, window = _start(qtbot)
    try:
        assert any("settings folder" in m and "is a file" in m
                   for m in window.error_bar.messages())
    finally:
        window.close()


QUITS = 6  # the segfault this guards against came about once in 6 quits


@pytest.mark.slow
def test_quitting_with_only_the_left_view_shown_never_crashes(tmp_path, sim_rig):
    """With `"visible_views": ["left"]`, quits from the Live tab with a calibration loaded, N
    times, every one exit 0: a hidden view (a top-level widget of its own) is not destroyed from
    inside its own image item's destructor while the interpreter tears down (a segfault, exit
    139)."""
    import json

    from stereo_gui.files.calibration_file import save_calibration

    calib = tmp_path / "calib.yaml"
    save_calibration(sim_rig.true_calibration(), calib)
    for i in range(QUITS):
        cfg = tmp_path / f"cfg{i}"
        cfg.mkdir()
        (cfg / "settings.json").write_text(json.dumps(
            {"format_version": 1, "source": "sim", "visible_views": ["left"]}))
        proc = subprocess.run(
            [sys.executable, "-X", "faulthandler", "-m", "stereo_gui", "--source", "sim",
             "--calib", str(calib)],
            env=_env(tmp_path, STEREO_GUI_CONFIG_DIR=str(cfg),
                     STEREO_GUI_DATA_DIR=str(tmp_path / f"data{i}"), STEREO_GUI_QUIT_AFTER="2"),
            capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, f"quit {i + 1} of {QUITS}: exit {proc.returncode}\n" \
                                     f"{proc.stderr[-3000:]}"
        assert "Fatal Python error" not in proc.stderr


def test_start_up_objects_are_frozen_and_later_ones_still_collected():
    """run_app freezes what start-up made (a full collection on the UI thread walked it all
    again, 17-24 ms while live); an object cycle made afterwards is still collected."""
    import gc
    import weakref

    from stereo_gui.qt.app import freeze_startup_objects

    class Node:
        pass

    try:
        assert freeze_startup_objects() == gc.get_freeze_count() > 0
        later = Node()
        later.me = later
        alive = weakref.ref(later)
        del later
        gc.collect()
        assert alive() is None
    finally:
        gc.unfreeze()  # the rest of the test session collects as before


def test_a_closed_windows_garbage_is_freed_on_the_ui_thread_before_the_next_window(qtbot):
    """Qt objects left in reference cycles (a closed window's widgets) are freed on the UI
    thread when a window is built: freed by a collection in a worker, their destructor can
    deadlock with the UI thread."""
    import gc
    import threading

    from PySide6.QtCore import QObject

    from stereo_gui.qt.app import free_garbage_on_ui_thread

    freed_in: list[str] = []

    class Widgetish:
        def __init__(self) -> None:
            self.me = self  # a cycle: only the collector frees it
            self.qobject = QObject()

        def __del__(self) -> None:
            freed_in.append(threading.current_thread().name)

    was_enabled = gc.isenabled()
    gc.disable()  # (so that nothing but the call below collects)
    try:
        Widgetish()
        assert not freed_in
        assert free_garbage_on_ui_thread() >= 1
    finally:
        if was_enabled:
            gc.enable()
    assert freed_in == [threading.current_thread().name]
