"""The application shell: start and auto-quit, the Qt binding's soundness, start-up arguments."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest
from PySide6.QtCore import QObject, Signal


class _Emitter(QObject):
    ping = Signal()
    value = Signal(object)


def test_signal_emit_keeps_bool_references(qapp):
    """PySide6 6.12.0 drops a reference to True on every Python emit(); a live view emits
    thousands of signals and the interpreter aborts ("bool_dealloc"). pyproject excludes it."""
    e = _Emitter()
    e.ping.connect(lambda: None)
    e.value.connect(lambda v: None)
    before = sys.getrefcount(True)
    for _ in range(200):
        e.ping.emit()
        e.value.emit(1)
    assert sys.getrefcount(True) >= before - 5


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
